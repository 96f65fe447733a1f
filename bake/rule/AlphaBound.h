#pragma once
/// @file AlphaBound.h
/// @brief The alpha test of a whole group of light samples at once: for a receiver and an alpha
/// triangle, the hits of every sample in a convex bound lie in one region of the triangle, and
/// when the map is opaque (or clear) all over it, no hit needs its own test.
///
/// Why it is exact. E_e(l) = det(l - w a_e, b_e - a_e, r - a_e) is linear in the sample l, so
/// each barycentric b = E_e / (E_0 + E_1 + E_2) is a linear-fractional function of l. Where the
/// denominator keeps one sign over the bound, it maps the bound's convex hull onto the convex hull
/// of its vertices' images. The caster's per-hit barycentrics (AlphaRule.h) are these values
/// after rounding, and the rounding of E_e is at most 16 u |l - w a|_1 |b - a|_1 |r - a|_1 for
/// either evaluation (the rule's cross product, or the vertices' (l - w a) . ((b - a) x (r - a))).
/// From that bound and the smallest denominator, alphaOverBound() pads the vertices' barycentrics
/// so that every hit's computed barycentrics lie in the padded hull, and AlphaTable::verdictOver()
/// only answers Opaque or Clear when every lookup there certainly gives it. A bound whose
/// denominator comes near 0 (the light reaching T's plane) stays Mixed.

#include "bake/rule/BlockingRule.h"
#include "bake/rule/ConvexBound.h"
#include "stream/AlphaTable.h"

namespace penumbra {

/// @brief The alpha test's result shared by every relation from a sample in @p bound to @p r
/// that the rule blocks with the alpha triangle @p t (AlphaRule.h, alphaAtEdges()).
/// @return Opaque: every such hit passes; Clear: none does; Mixed: test each hit. An id with a
/// max_distance is never Opaque (its distance test is per hit).
AlphaVerdict alphaOverBound(const AlphaTable& table, const BlockerTriangle& t, const glm::dvec3& r, const ConvexBound& bound);

}  // namespace penumbra
