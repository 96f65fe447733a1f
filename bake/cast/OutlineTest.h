#pragma once
/// @file OutlineTest.h
/// @brief The alpha test of an analytic outline (a leaf or a petal) for the four lanes of a
/// hard-shadow block at once.
///
/// FLOWERS' per-hit alpha tests were a fifth of its profile at 1,024 samples: three edge values,
/// three divisions, the UV mix and the outline, one hit at a time through AlphaTable::lookup().
/// outlineLanesAvx2() runs alphaAtEdges()'s operations (AlphaRule.h: laneEdgeValue(), the
/// barycentrics, lookup()'s UV, transform and outline expressions) in the same order in every lane,
/// with no fused multiply-add (the project builds with -ffp-contract=off and the AVX2 target has
/// no FMA), so each lane's verdict is the scalar test's; tests/bake/test_alpha_bound.cpp compares
/// them lane by lane.

#include "bake/cast/HardShadowBlock.h"
#include "stream/AlphaTable.h"

#include <cstdint>

namespace penumbra {

/// @brief Of the lanes in @p lanes (bits 0-3) of block @p h, those whose hit passes the outline
/// @p o's test, for the receiver at offsets @p at.
/// @pre the CPU has AVX2; the lanes in @p lanes block the receiver (their edge values are >= 0)
uint32_t outlineLanesAvx2(const HardShadowBlock& h, uint32_t lanes, const EdgeOffsets& at, const AlphaOutline& o);

}  // namespace penumbra
