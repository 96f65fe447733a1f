#pragma once
/// @file AlphaRule.h
/// @brief The blocking rule for cut-out triangles: a relation that the rule of BlockingRule.h
/// blocks with an alpha triangle stays blocked only when the hit passes the alpha test.
///
/// The hit's barycentrics come from the rule's own edge values, not from a separate
/// ray-plane intersection: E_e is s det(l - w a, b - a, r - a), the scaled volume spanned by the
/// segment and edge e, which is proportional to the barycentric coordinate of the vertex opposite
/// edge e (Plücker coordinates). So b_(e+2 mod 3) = E_e / (E_0 + E_1 + E_2), from exactly the
/// double values every method already computes, and the alpha test adds no new kind of tie
/// beyond the texel edges and outlines of AlphaLookup::tie.
/// Penumbra volumes, sample tables and umbra bits need no change to stay exact: an alpha triangle
/// blocks a subset of what its opaque twin blocks, so the conservative tests stay conservative, as
/// long as nothing marks a relation blocked without this test (TileCaster.cpp).
/// A scene entry's "max_distance" rides on the same route: its triangles get alpha ids whose
/// entry limits the distance of the hit from the receiver (AlphaTable::withDistance), so they too
/// block a subset of what their unlimited twins block and every method tests each hit exactly.

#include "bake/rule/BlockingRule.h"
#include "stream/AlphaTable.h"

namespace penumbra {

/// @brief The barycentrics of the hit from the rule's three edge values @p e (all >= 0):
/// b_(e+2 mod 3) = E_e / (E_0 + E_1 + E_2); a vertex-on ray (sum 0) takes the centroid.
inline void barycentricsAtEdges(const double e[3], double b[3]) {
    const double sum = (e[0] + e[1]) + e[2];
    if (!(sum > 0.0)) {
        b[0] = b[1] = b[2] = 1.0 / 3.0;
        return;
    }
    b[0] = e[1] / sum, b[1] = e[2] / sum, b[2] = e[0] / sum;
}

/// @brief A scene entry's "max_distance" (AlphaEntry::maxDistance): the hit at barycentrics
/// @p b blocks only when |hit - r| <= @p limit. The hit is the barycentric mix of T's vertices,
/// from the same edge values as the texture test, so every method measures the same double.
/// Within 2^-40 of the coordinates' scale of the limit it is a tie (TieClassifier.h).
inline AlphaLookup distanceAtHit(double limit, const BlockerTriangle& t, const glm::dvec3& r, const double b[3]) {
    const glm::dvec3 hit = (b[0] * t.v[0] + b[1] * t.v[1]) + b[2] * t.v[2];
    const double d = glm::length(hit - r);
    const double scale = std::max({limit, std::abs(r.x), std::abs(r.y), std::abs(r.z), std::abs(hit.x), std::abs(hit.y),
                                   std::abs(hit.z)});
    return {d <= limit, std::abs(d - limit) <= 0x1p-40 * scale};
}

/// @brief The alpha test of a relation that the rule blocks, from its three edge values @p e
/// (edgeValue(h, t, e, r), all >= 0): the map's opacity and, for an id with a max_distance, the
/// distance of the hit. The caster passes the values its hard-shadow blocks hold, which are the
/// same doubles (HardShadowBlock.h), without rebuilding the volume.
inline AlphaLookup alphaAtEdges(const AlphaTable& table, const BlockerTriangle& t, const glm::dvec3& r, const double e[3]) {
    double b[3];
    barycentricsAtEdges(e, b);
    const AlphaLookup map = table.lookup(t.alpha, b[0], b[1], b[2]);
    const double limit = table.maxDistance(t.alpha);
    if (!(limit < INFINITY)) return map;
    const AlphaLookup near = distanceAtHit(limit, t, r, b);
    return {map.opaque && near.opaque, map.tie || near.tie};
}

/// @brief The alpha test of the hit of (@p h, @p r) on @p t, which blocks() must already block.
inline AlphaLookup alphaAtHit(const AlphaTable& table, const HardShadowVolume& h, const BlockerTriangle& t,
                              const glm::dvec3& r) {
    const double e[3] = {edgeValue(h, t, 0, r), edgeValue(h, t, 1, r), edgeValue(h, t, 2, r)};
    return alphaAtEdges(table, t, r, e);
}

/// @brief The whole rule with alpha: blocks() and, for an alpha triangle, the alpha test.
inline bool blocksWithAlpha(const HardShadowVolume& h, const BlockerTriangle& t, const glm::dvec3& r, double distToPlane,
                            double eps, const AlphaTable& table) {
    if (!blocks(h, t, r, distToPlane, eps)) return false;
    return t.alpha == 0 || alphaAtHit(table, h, t, r).opaque;
}

/// @brief Convenience form for one relation (the reference method, tests).
inline bool blocksWithAlpha(const glm::dvec3& l, double w, const glm::dvec3& r, const BlockerTriangle& t,
                            const ReceiverEpsilon& epsilon, const AlphaTable& table) {
    if (!t.valid) return false;
    const HardShadowVolume h = makeHardShadowVolume(l, w, t);
    return blocksWithAlpha(h, t, r, distanceBehind(t, r), epsilon.at(r), table);
}

}  // namespace penumbra
