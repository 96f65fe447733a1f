#pragma once
/// @file PenumbraVolumeBuilder.h
/// @brief Internal to PenumbraVolume.cpp and PenumbraVolumeAvx2.cpp: the state of one
/// buildPenumbraVolume() call and the rules that accept a candidate plane, shared by the scalar
/// and the AVX2 evaluation of the candidates so that both give the same volume, plane for plane.
///
/// Candidates come in two families (Laine & Aila 2005, Section 3.2):
///  1. through an edge (a, c) of T and a bound vertex b: normal (c - a) x (b - w a);
///  2. through a bound edge (p, q) and a vertex v of T: normal (p - w v) x (q - p).
/// A candidate is accepted when T lies on its positive side and the bound on the other, both up
/// to a tolerance relative to the scene's scale; the points that define it are not evaluated.

#include "bake/cast/PenumbraVolume.h"

#include <glm/geometric.hpp>

#include <cmath>

namespace penumbra::volume_detail {

// Relative tolerances. kAccept decides whether a candidate plane separates (defining vertices
// evaluate to roundoff, not zero); kMargin pushes accepted planes outward. kMargin >> kAccept
// keeps the volume conservative for receivers up to ~1000x farther from the blocker than the
// blocker is from the light (see docs/design.md, "Conservativeness").
constexpr double kAccept = 1e-12;
constexpr double kMargin = 1e-9;
/// Bounds have at most 16 vertices (an octagon prism); a larger one gets no planes at all.
constexpr size_t kMaxBoundVertices = 64;
constexpr size_t kNone = ~size_t(0);

struct Builder {
    const ConvexBound& bound;
    const BlockerTriangle& t;
    PenumbraVolume& volume;
    double scale = 1.0;
    const Box* cull = nullptr;  ///< stop as soon as an accepted plane leaves this box outside
    bool culled = false;
    /// Directions only: (|b|_inf / scale)^2 per bound vertex, the scale of its tolerance.
    const double* boundTolerance2 = nullptr;

    /// (tolerance |n|)^2 for a candidate normal with |n|^2 = @p nn, in this operation order
    /// (the AVX2 lanes multiply the same prefix by their nn).
    double tolerancePrefix() const { return kAccept * scale * kAccept * scale; }
    /// Bound vertex @p i's squared tolerance for a candidate with (tolerance |n|)^2 = @p tol2.
    double boundTolerance(size_t i, double tol2) const { return bound.w == 0.0 ? tol2 * boundTolerance2[i] : tol2; }

    /// The accepted candidate @p normal, oriented by @p s (T on the positive side), through
    /// @p anchor: normalised and added.
    void accept(const glm::dvec3& normal, double nn, double s, const glm::dvec3& anchor) {
        const double len = std::sqrt(nn);
        const glm::dvec3 unit = normal * (s / len);
        add(Plane{unit, -glm::dot(unit, anchor)});
    }

    void add(Plane p) {
        p.d += kMargin * scale;
        for (int i = 0; i < volume.count; ++i) {
            const Plane q = volume.plane(i);
            if (glm::dot(q.n, p.n) > 1.0 - 1e-12 && std::abs(q.d - p.d) <= kAccept * scale) return;
        }
        if (volume.count < PenumbraVolume::kMaxPlanes) volume.push(p);
        // Dropping a plane beyond the limit only enlarges the volume: still conservative.
        if (cull && !culled) culled = classify(p, *cull) == BoxSide::Outside;
    }
};

/// Evaluates both families of candidates in the scalar order (family 1 by T's edge, then bound
/// vertex; family 2 by bound edge, then T's vertex), accepting into @p b until it is culled.
void addCandidatesScalar(Builder& b);
/// The same candidates, accepted in the same order with the same values, four at a time.
void addCandidatesAvx2(Builder& b);

}  // namespace penumbra::volume_detail
