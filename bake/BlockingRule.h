#pragma once
/// @file BlockingRule.h
/// @brief The one definition of "triangle T blocks the relation from light sample l to receiver r".
///
/// Every method (hierarchical penumbra casting, the brute-force reference, and the tie
/// classifier used against Embree) decides individual relations with the functions in this file,
/// evaluated in the same order in double precision, so that methods sharing them agree bit for bit.
///
/// The rule (docs/design.md, "Blocking rule"):
///  - T blocks l -> r when the open segment from r to l passes through T (edges included) and r
///    lies more than eps(r) behind T's plane, measured perpendicular to that plane on the side
///    away from l. eps(r) = epsilon * max(1, max_i |r_i|) is the receiver-end epsilon.
///  - A receiver lying on T (distance below eps) is never shadowed through T: this is what stops a
///    surface from shadowing itself at the point where it was sampled.
///  - A sample lying exactly in T's plane is never blocked by T (the segment only touches the plane
///    at its open end), and a triangle with zero area blocks nothing.
///  - Vertices are the float32 values of the stream, promoted to double; receivers and samples are
///    float32 values promoted to double.
/// A relation is a *tie* when one of the tested quantities is within roundoff of its threshold;
/// only ties can differ between this rule and an independent float implementation such as Embree.

#include "bake/Plane.h"
#include "stream/Triangle.h"

#include <algorithm>
#include <cmath>

namespace penumbra {

/// @brief A blocker triangle promoted to double, with its unit-normal plane.
struct BlockerTriangle {
    glm::dvec3 v[3];
    Plane plane;          ///< unit normal, so eval() is a signed distance
    bool valid = false;   ///< false for zero-area or non-finite triangles: they block nothing

    static BlockerTriangle from(const Triangle& t) {
        BlockerTriangle b;
        for (int i = 0; i < 3; ++i) b.v[i] = glm::dvec3(t.v[i]);
        glm::dvec3 n = glm::cross(b.v[1] - b.v[0], b.v[2] - b.v[0]);
        double len = glm::length(n);
        b.valid = len > 0.0 && std::isfinite(len);
        if (b.valid) b.plane = Plane::through(n / len, b.v[0]);
        return b;
    }
};

/// @brief The receiver-end epsilon for a receiver at @p r (scale-relative, see the rule above).
inline double receiverEpsilon(const glm::dvec3& r, double epsilon) {
    double m = std::max({1.0, std::abs(r.x), std::abs(r.y), std::abs(r.z)});
    return epsilon * m;
}

/// @brief The hard-shadow volume V_l of one light sample and one triangle: three edge planes
/// through the sample plus T's plane, oriented so that blocked receivers are on the positive side.
struct HardShadowVolume {
    Plane edge[3];
    double side = 0.0;  ///< +1 or -1: the sign of T's plane on the far side from l; 0 blocks nothing
};

/// @brief Builds V_l for sample @p l and triangle @p t (which must be valid).
inline HardShadowVolume makeHardShadowVolume(const glm::dvec3& l, const BlockerTriangle& t) {
    HardShadowVolume h;
    double sl = t.plane.eval(l);
    if (sl == 0.0) return h;  // sample in T's plane: never blocked
    h.side = sl > 0.0 ? -1.0 : 1.0;
    for (int e = 0; e < 3; ++e) {
        const glm::dvec3& a = t.v[e];
        const glm::dvec3& b = t.v[(e + 1) % 3];
        const glm::dvec3& c = t.v[(e + 2) % 3];
        glm::dvec3 n = glm::cross(a - l, b - l);
        Plane p = Plane::through(n, l);
        h.edge[e] = p.eval(c) >= 0.0 ? p : p.flipped();
    }
    return h;
}

/// @brief Signed distance of @p r behind T as seen from samples on side @p side (precomputable
/// per receiver: it does not depend on the sample beyond its side).
inline double distanceBehind(const BlockerTriangle& t, const glm::dvec3& r) { return t.plane.eval(r); }

/// @brief The rule itself, given the receiver's distance to T's plane (distanceBehind()).
inline bool blocks(const HardShadowVolume& h, const glm::dvec3& r, double distToPlane, double eps) {
    return h.side * distToPlane > eps && h.edge[0].eval(r) >= 0.0 && h.edge[1].eval(r) >= 0.0 &&
           h.edge[2].eval(r) >= 0.0;
}

/// @brief Convenience form for one relation (the reference method and tests).
inline bool blocks(const glm::dvec3& l, const glm::dvec3& r, const BlockerTriangle& t, double epsilon) {
    if (!t.valid) return false;
    HardShadowVolume h = makeHardShadowVolume(l, t);
    return blocks(h, r, distanceBehind(t, r), receiverEpsilon(r, epsilon));
}

/// @brief True when the rule's decision for (l, r, t) sits within @p tolerance (relative) of a
/// threshold, so an independent float implementation may legitimately decide it the other way.
bool isTie(const glm::dvec3& l, const glm::dvec3& r, const BlockerTriangle& t, double epsilon,
           double tolerance = 1e-5);

}  // namespace penumbra
