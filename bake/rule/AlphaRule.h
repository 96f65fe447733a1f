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

#include "bake/rule/BlockingRule.h"
#include "stream/AlphaTable.h"

namespace penumbra {

/// @brief The alpha test of a relation that blocks(h, t, r, ...) blocks, given its three edge
/// values @p e (edgeValue(h, t, e, r), all >= 0).
inline AlphaLookup alphaAtEdges(const AlphaTable& table, uint32_t alpha, const double e[3]) {
    const double sum = (e[0] + e[1]) + e[2];
    if (!(sum > 0.0)) return table.lookup(alpha, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0);  // a vertex-on ray
    return table.lookup(alpha, e[1] / sum, e[2] / sum, e[0] / sum);
}

/// @brief The alpha test of the hit of (@p h, @p r) on @p t, which blocks() must already block.
inline AlphaLookup alphaAtHit(const AlphaTable& table, const HardShadowVolume& h, const BlockerTriangle& t,
                              const glm::dvec3& r) {
    const double e[3] = {edgeValue(h, t, 0, r), edgeValue(h, t, 1, r), edgeValue(h, t, 2, r)};
    return alphaAtEdges(table, t.alpha, e);
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
