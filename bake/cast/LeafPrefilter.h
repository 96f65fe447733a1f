#pragma once
/// @file LeafPrefilter.h
/// @brief The cheap first tests of castReceiver(), for four receivers of a leaf at once.
///
/// Under a large light most receiver-blocker pairs that reach a leaf end in these tests: the
/// receiver lies outside V_L, or within its epsilon of T's plane, or in front of a closed face
/// (GRIDS under the 4x light: 31 % of the calls leave at V_L, another 6 % at T's plane). One
/// receiver at a time they cost a loop over V_L's plane pairs each; four at a time, one AVX2 pass
/// per plane. Every lane runs the scalar test's operations in the scalar order (the project builds
/// with -ffp-contract=off and the AVX2 target has no FMA), so the same receivers pass and the
/// distances are the same bits; tests/bake/test_leaf_prefilter.cpp compares them.

#include "bake/cast/HardShadowBlock.h"
#include "bake/cast/PenumbraVolume.h"
#include "bake/rule/BlockingRule.h"

#include <cstdint>

namespace penumbra {

/// @brief Whether castReceiver() goes past its first tests for the receiver at @p p: inside the
/// active planes @p planes of @p lightVolume, and beyond @p eps from T's plane on either side
/// (behind it only, for a closed T). Sets @p dist to distanceBehind(t, p) when it returns true.
inline bool passesLeafPrefilter(const PenumbraVolume& lightVolume, uint32_t planes, const BlockerTriangle& t,
                                const glm::dvec3& p, double eps, double& dist) {
    if (!contains(lightVolume, p, planes)) return false;  // Figure 3, line 58
    dist = distanceBehind(t, p);
    if (!(dist > eps) && !(-dist > eps)) return false;  // the rule blocks nothing this close to T's plane
    return !(t.closed && dist > eps);                     // in front of a closed face (TileCaster.cpp)
}

/// @brief passesLeafPrefilter() for @p count (1 to 4) consecutive receivers, AVX2.
/// @param positions, epsilons the receivers (at least @p count of each)
/// @param dist out: for each receiver that passes, its distanceBehind(t, p), the scalar value's bits
/// @return bit i set when receiver i passes
/// @pre the CPU has AVX2 (hardShadowKernels(level).level == SimdLevel::Avx2)
uint32_t leafPrefilterAvx2(const PenumbraVolume& lightVolume, uint32_t planes, const BlockerTriangle& t,
                           const glm::dvec3* positions, const double* epsilons, int count, double dist[4]);

}  // namespace penumbra
