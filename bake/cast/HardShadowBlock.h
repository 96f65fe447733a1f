#pragma once
/// @file HardShadowBlock.h
/// @brief Four hard-shadow volumes in structure-of-arrays form, built and tested against a
/// receiver four samples at a time with SSE2 or AVX2 (chosen at run time).
///
/// Exactness: the kernels evaluate exactly the double-precision expressions of BlockingRule.h,
/// operation for operation and in the same order (dot products as (x + y) + z, cross products as
/// glm computes them, every edge plane evaluated at r - v_e), with no fused multiply-add (the AVX2 code is compiled for
/// "avx2" without "fma", and the project builds with -ffp-contract=off). IEEE arithmetic is then
/// the same in every lane as in the scalar code, so the SIMD result equals blocks() bit for bit;
/// tests/test_hard_shadow_block.cpp checks it lane by lane and through the whole caster.
/// Double precision is kept on purpose: a float pre-test with a double fallback near the planes
/// needs a rigorous error bound per test and a second pass, and measured no faster than four
/// double lanes here (docs/performance.md).

#include "bake/cast/SimdLevel.h"
#include "bake/rule/BlockingRule.h"

#include <glm/vec3.hpp>

#include <cstdint>

namespace penumbra {


/// @brief Hard-shadow volumes (BlockingRule.h) of up to four light samples and one triangle.
/// Lane i holds the normal of edge plane e as (nx[e][i], ny[e][i], nz[e][i]) (anchored at the
/// triangle's vertex e) and the side sign in side[i]. Unused lanes and samples in T's plane have
/// side 0, which blocks nothing.
struct alignas(32) HardShadowBlock {
    static constexpr int kLanes = 4;
    double nx[3][kLanes], ny[3][kLanes], nz[3][kLanes];
    double side[kLanes];
};

/// @brief Blocks that hold @p samples consecutive samples (a group's).
constexpr size_t hardShadowBlocksFor(uint32_t samples) { return (samples + HardShadowBlock::kLanes - 1) / HardShadowBlock::kLanes; }

/// @brief The blocks that hold a sample of @p samples: bit b is set when any of bits 4b..4b+3 is.
/// Branch-free (nibbles folded to their low bit, then packed): the loop over set bits it replaces
/// mispredicted on every pair of GRIDS under a large light (docs/performance.md).
constexpr uint32_t blocksHolding(uint64_t samples) {
    static_assert(HardShadowBlock::kLanes == 4, "one nibble per block");
    uint64_t x = samples | (samples >> 1);
    x = (x | (x >> 2)) & 0x1111111111111111ull;  // bit 4b: block b holds a sample
    x = (x | (x >> 3)) & 0x0303030303030303ull;  // two blocks per byte
    x = (x | (x >> 6)) & 0x000F000F000F000Full;  // four per 16 bits
    x = (x | (x >> 12)) & 0x000000FF000000FFull; // eight per 32 bits
    return uint32_t((x | (x >> 24)) & 0xFFFFull);
}

/// @brief Builds the block for @p count (1..4) consecutive samples starting at @p samples, all of
/// homogeneous weight @p w (1: points, 0: directions; one light's samples share it).
using BuildBlockFn = void (*)(HardShadowBlock& out, const glm::vec3* samples, int count, double w,
                              const BlockerTriangle& t);

/// @brief The receiver relative to each edge plane's anchor: rel[e] = r - t.v[e].
struct EdgeOffsets {
    glm::dvec3 rel[3];
    EdgeOffsets() = default;
    EdgeOffsets(const BlockerTriangle& t, const glm::dvec3& r) : rel{r - t.v[0], r - t.v[1], r - t.v[2]} {}
};

/// @brief Edge @p e's plane of lane @p i evaluated at the receiver: the kernels' expression, in
/// glm::dot's order, so it is the very double edgeValue() gives for that sample (the lane's
/// normal is the rule's cross product). The alpha test reads the hit's barycentrics from it.
inline double laneEdgeValue(const HardShadowBlock& h, int e, int i, const EdgeOffsets& at) {
    const glm::dvec3& q = at.rel[e];
    return (h.nx[e][i] * q.x + h.ny[e][i] * q.y) + h.nz[e][i] * q.z;
}

/// @brief Tests a receiver against the blocks selected by @p which (bit b: blocks[b]).
/// @param at the receiver relative to the edge anchors; @param dist distanceBehind(t, r);
/// @param eps the receiver's epsilon.
/// @return bit 4b+i set when lane i of block b blocks r (the sample blocks the relation).
using TestBlocksFn = uint64_t (*)(const HardShadowBlock* blocks, uint32_t which, const EdgeOffsets& at, double dist,
                                  double eps);

/// @brief The build and test kernels of one instruction set.
struct HardShadowKernels {
    SimdLevel level = SimdLevel::Scalar;
    BuildBlockFn build = nullptr;
    TestBlocksFn test = nullptr;
};

/// @brief The kernels for @p level; Auto resolves to the best level this CPU supports.
/// @throw InputError when @p level is not supported by this CPU.
HardShadowKernels hardShadowKernels(SimdLevel level);

}  // namespace penumbra
