#include "bake/cast/PenumbraVolume.h"

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

// Relative tolerances. kAccept decides whether a candidate plane separates (defining vertices
// evaluate to roundoff, not zero); kMargin pushes accepted planes outward. kMargin >> kAccept
// keeps the volume conservative for receivers up to ~1000x farther from the blocker than the
// blocker is from the light (see docs/design.md, "Conservativeness").
constexpr double kAccept = 1e-12;
constexpr double kMargin = 1e-9;
/// Bounds have at most 16 vertices (an octagon prism); a larger one gets no planes at all.
constexpr size_t kMaxBoundVertices = 64;

struct Builder {
    const ConvexBound& bound;
    const BlockerTriangle& t;
    PenumbraVolume& volume;
    double scale = 1.0;
    const Box* cull = nullptr;  ///< stop as soon as an accepted plane leaves this box outside
    bool culled = false;
    /// Directions only: (|b|_inf / scale)^2 per bound vertex, the scale of its tolerance.
    const double* boundTolerance2 = nullptr;

    /// Adds the plane through @p anchor (a vertex of T) with normal ±@p normal if it separates T
    /// (positive side) from the bound. Every value is taken relative to the anchor, and a bound
    /// vertex b of weight w as b - w anchor, so a far or infinite light costs no precision.
    /// Candidates are judged unnormalised, comparing squares against the tolerance, because most
    /// are rejected; only accepted planes are normalised. The points that define the candidate
    /// (triangle vertices @p triOn, a bit set, and bound vertices @p boundOnA / @p boundOnB) lie
    /// on it up to roundoff far below the tolerance, so they are not evaluated: that halves the
    /// work per candidate.
    void tryPlane(const glm::dvec3& normal, const glm::dvec3& anchor, unsigned triOn, size_t boundOnA,
                  size_t boundOnB) {
        const double nn = glm::dot(normal, normal);
        if (!(nn > 0.0) || !std::isfinite(nn)) return;
        const double tol2 = kAccept * scale * kAccept * scale * nn;  // (tolerance * |n|)^2
        // Orientation from the triangle vertex farthest from the plane; then every vertex must
        // agree. Most candidates fail on an early vertex, so bail out as soon as one does.
        double e[3] = {0.0, 0.0, 0.0}, far = 0.0;
        for (int i = 0; i < 3; ++i) {
            if (triOn >> i & 1u) continue;
            e[i] = glm::dot(normal, t.v[i] - anchor);
            if (std::abs(e[i]) > std::abs(far)) far = e[i];
        }
        const double s = far < 0.0 ? -1.0 : 1.0;  // triangle on the positive side
        for (double v : e)
            if (s * v < 0.0 && v * v > tol2) return;
        const double w = bound.w;
        for (size_t i = 0; i < bound.vertices.size(); ++i) {
            if (i == boundOnA || i == boundOnB) continue;
            const double x = s * glm::dot(normal, bound.vertices[i] - w * anchor);
            // A direction's value is on the scale of the direction (about 1), not of the scene.
            if (x > 0.0 && x * x > (w == 0.0 ? tol2 * boundTolerance2[i] : tol2)) return;
        }
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

}  // namespace

PenumbraVolume makePenumbraVolume(const ConvexBound& bound, const BlockerTriangle& t) {
    PenumbraVolume volume;
    buildPenumbraVolume(bound, t, volume);
    return volume;
}

namespace {

double volumeScale(const ConvexBound& bound, const BlockerTriangle& t) {
    double scale = 1.0;
    for (const glm::dvec3& v : bound.vertices) scale = std::max({scale, std::abs(v.x), std::abs(v.y), std::abs(v.z)});
    for (const glm::dvec3& v : t.v) scale = std::max({scale, std::abs(v.x), std::abs(v.y), std::abs(v.z)});
    return scale;
}

/// The cap of the volume (T's plane, oriented away from the bound), or false when T's plane cuts
/// the bound. A bound vertex's side is taken relative to T (BlockerTriangle::side()).
bool capPlane(const ConvexBound& bound, const BlockerTriangle& t, double scale, Plane& cap) {
    double lo = INFINITY, hi = -INFINITY;
    for (const glm::dvec3& v : bound.vertices) {
        double e = t.side(v, bound.w);
        lo = std::min(lo, e), hi = std::max(hi, e);
    }
    const double tol = kAccept * (bound.directional() ? 1.0 : scale);
    if (hi < -tol) cap = t.plane;
    else if (lo > tol) cap = t.plane.flipped();
    else return false;
    return true;
}

}  // namespace

bool buildPenumbraVolume(const ConvexBound& bound, const BlockerTriangle& t, PenumbraVolume& volume,
                         const Box* cull) {
    volume.count = 0;
    volume.nx[0] = volume.ny[0] = volume.nz[0] = volume.d[0] = 0.0;  // the slot after the last
    Builder b{bound, t, volume, volumeScale(bound, t), cull};

    // Cap first: it is the plane most likely to reject a box, and order is the test order.
    Plane cap;
    if (capPlane(bound, t, b.scale, cap)) b.add(cap);

    double boundTolerance2[kMaxBoundVertices];  // filled for directions only (kept unzeroed)
    if (bound.vertices.size() > kMaxBoundVertices) return !b.culled;  // (never: at most 16) no planes: all space
    if (bound.directional()) {
        for (size_t i = 0; i < bound.vertices.size(); ++i) {
            const glm::dvec3& v = bound.vertices[i];
            const double m = std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}) / b.scale;
            boundTolerance2[i] = m * m;
        }
        b.boundTolerance2 = boundTolerance2;
    }
    constexpr size_t kNone = ~size_t(0);
    const double w = bound.w;
    for (int e = 0; e < 3; ++e) {
        const glm::dvec3& a = t.v[e];
        const glm::dvec3& c = t.v[(e + 1) % 3];
        const unsigned on = (1u << e) | (1u << (e + 1) % 3);
        for (size_t i = 0; i < bound.vertices.size() && !b.culled; ++i)
            b.tryPlane(glm::cross(c - a, bound.vertices[i] - w * a), a, on, i, kNone);
    }
    // Through an edge (p, q) of the bound and a vertex v of T: normal (p - w v) x (q - p), which
    // needs no difference of two far, nearly parallel vectors; for directions, p x q.
    for (const auto& edge : bound.edges) {
        const glm::dvec3& p = bound.vertices[edge[0]];
        const glm::dvec3& q = bound.vertices[edge[1]];
        const glm::dvec3 along = q - p;
        for (int i = 0; i < 3 && !b.culled; ++i)
            b.tryPlane(glm::cross(p - w * t.v[i], along), t.v[i], 1u << i, edge[0], edge[1]);
    }
    return !b.culled;
}

}  // namespace penumbra
