#pragma once
/// @file BlockingRule.h
/// @brief The one definition of "triangle T blocks the relation from light sample l to receiver r".
///
/// Every method (hierarchical penumbra casting, the brute-force reference, the Embree peer's hit
/// filter and the tie classifier of `penumbra compare`) decides individual relations with the
/// functions in this file, evaluated in the same order in double precision, so that methods
/// sharing them agree bit for bit.
///
/// A light sample is homogeneous: a point l (w = 1) or, for a sun, a direction d towards the
/// light at infinity (w = 0). The rule, in exact arithmetic on the float inputs (docs/design.md,
/// "The blocking rule"), with N = (v1 - v0) x (v2 - v0) and s = sign(N . (l - w v0)):
///  - T blocks nothing when N = 0 (zero area), a vertex is not finite, or s = 0 (a point sample
///    in T's plane, a direction parallel to it).
///  - Otherwise T blocks l -> r when, for each edge (a, b) = (v_e, v_e+1),
///      E_e = s det(l - w a, b - a, r - a) >= 0           (the segment or ray passes through T,
///                                                          edges included)
///    and r lies more than eps(r) behind T's plane on the side away from the light:
///      -s N . (r - v0) / |N| > eps(r),   eps(r) = epsilon * max(|r|_inf, L).
///    epsilon is relative (bake.epsilon) and L is the scene length fixed after the scan pass
///    (the largest |coordinate| of any receiver), so a uniformly scaled scene has the same masks.
/// Every plane is anchored at a vertex of T, never at the (possibly far) sample, so a far or
/// infinite light loses no precision near the receivers. Vertices, receivers and samples are
/// float32 values promoted to double; differences of two such values are exact in double for
/// every scene whose coordinates span fewer than 29 binary orders of magnitude.
/// A relation is a *tie* when one of the tested quantities is within roundoff of its threshold
/// (bake/TieClassifier.h); only ties can differ between this rule and an independent float
/// implementation such as Embree.

#include "bake/rule/Plane.h"
#include "stream/Triangle.h"

#include <algorithm>
#include <cmath>

namespace penumbra {

/// @brief A blocker triangle promoted to double, with its unit normal.
struct BlockerTriangle {
    glm::dvec3 v[3];
    Plane plane;          ///< unit normal through v[0]: eval() is a signed distance (box tests)
    bool valid = false;   ///< false for zero-area or non-finite triangles: they block nothing
    uint32_t alpha = 0;   ///< alpha id (stream/AlphaTable.h); 0: opaque (AlphaRule.h tests the rest)
    /// HPC only (bake/cast/BlockerBatch.cpp): an opaque face of a closed solid wound outward, cast
    /// with closed casters on. It may skip every receiver in front of it (TileCaster.cpp).
    bool closed = false;

    static BlockerTriangle from(const Triangle& t) {
        BlockerTriangle b;
        for (int i = 0; i < 3; ++i) b.v[i] = glm::dvec3(t.v[i]);
        glm::dvec3 n = glm::cross(b.v[1] - b.v[0], b.v[2] - b.v[0]);
        double len = glm::length(n);
        b.valid = len > 0.0 && std::isfinite(len);
        b.alpha = alphaIdOf(t.flags);
        if (b.valid) b.plane = Plane::through(n / len, b.v[0]);
        return b;
    }

    /// @brief N̂ . (p - w v0): signed distance of a point (w = 1) from T's plane, or the component
    /// of a direction (w = 0) along the unit normal. Anchored at v0, so a far point loses nothing.
    double side(const glm::dvec3& p, double w) const { return glm::dot(plane.n, p - w * v[0]); }
};

/// @brief eps(r) = relative * max(|r|_inf, length): the receiver-end epsilon of the rule.
struct ReceiverEpsilon {
    double relative = 1e-5;  ///< bake.epsilon
    double length = 1.0;     ///< L, the scene length (set by the pipeline after the scan pass)

    double at(const glm::dvec3& r) const {
        return relative * std::max({length, std::abs(r.x), std::abs(r.y), std::abs(r.z)});
    }
};

/// @brief The hard-shadow volume V_l of one light sample and one triangle: three edge planes
/// through the sample, each anchored at its edge's first vertex, plus T's plane. Blocked receivers
/// are on the non-negative side of every edge plane.
struct HardShadowVolume {
    glm::dvec3 edge[3];   ///< normal of edge e's plane, anchored at t.v[e]
    double side = 0.0;    ///< +1 or -1: the sign of T's plane on the far side from l; 0 blocks nothing
};

/// @brief Builds V_l for sample (@p l, @p w) and triangle @p t (which must be valid). Edge planes
/// are oriented by the side of the sample (s above), never by evaluating the third vertex, so a
/// thin triangle seen edge-on cannot flip one edge alone.
inline HardShadowVolume makeHardShadowVolume(const glm::dvec3& l, double w, const BlockerTriangle& t) {
    HardShadowVolume h;
    const double sl = t.side(l, w);
    if (!(sl > 0.0) && !(sl < 0.0)) return h;  // sample in T's plane (or NaN): never blocked
    h.side = sl > 0.0 ? -1.0 : 1.0;
    const double s = -h.side;
    for (int e = 0; e < 3; ++e) {
        const glm::dvec3& a = t.v[e];
        const glm::dvec3& b = t.v[(e + 1) % 3];
        h.edge[e] = s * glm::cross(l - w * a, b - a);
    }
    return h;
}

/// @brief Signed distance of @p r from T's plane, anchored at v0 (precomputable per receiver: it
/// does not depend on the sample beyond its side).
inline double distanceBehind(const BlockerTriangle& t, const glm::dvec3& r) { return glm::dot(t.plane.n, r - t.v[0]); }

/// @brief The value of edge @p e's plane at @p r (>= 0: inside).
inline double edgeValue(const HardShadowVolume& h, const BlockerTriangle& t, int e, const glm::dvec3& r) {
    return glm::dot(h.edge[e], r - t.v[e]);
}

/// @brief The rule itself, given the receiver's distance to T's plane (distanceBehind()).
inline bool blocks(const HardShadowVolume& h, const BlockerTriangle& t, const glm::dvec3& r, double distToPlane,
                   double eps) {
    return h.side * distToPlane > eps && edgeValue(h, t, 0, r) >= 0.0 && edgeValue(h, t, 1, r) >= 0.0 &&
           edgeValue(h, t, 2, r) >= 0.0;
}

/// @brief Convenience form for one relation (the reference method, the Embree filter, tests).
inline bool blocks(const glm::dvec3& l, double w, const glm::dvec3& r, const BlockerTriangle& t,
                   const ReceiverEpsilon& epsilon) {
    if (!t.valid) return false;
    HardShadowVolume h = makeHardShadowVolume(l, w, t);
    return blocks(h, t, r, distanceBehind(t, r), epsilon.at(r));
}

}  // namespace penumbra
