#pragma once
/// @file BlockerBatch.h
/// @brief A chunk of blockers made ready for every tile: promoted to double, culled at the root,
/// with V_L per light.
///
/// The culls a blocker passes before any tile sees it, in order of cost: the reach box and hull
/// of each light (ReachHull.h), closed casters (Sintorn et al. 2008: a closed surface's triangle
/// that faces away from the whole light), and V_L itself, built plane by plane and abandoned as
/// soon as one plane leaves every receiver outside. A light is switched off per blocker as soon
/// as one cull drops it, and the blocker is dropped when no light is left.

#include "bake/rule/BlockingRule.h"
#include "bake/cast/CastOptions.h"
#include "bake/light/Light.h"
#include "bake/cast/PenumbraVolume.h"
#include "bake/rule/ReachHull.h"
#include "stream/Triangle.h"

#include <atomic>
#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

/// @brief One chunk of prepared blockers, and which tiles still have to cast it. Buffers are kept
/// between chunks to avoid reallocation.
struct BlockerBatch {
    size_t n = 0;
    std::vector<BlockerTriangle> prepared;     ///< valid == false: culled, nothing to cast
    std::vector<PenumbraVolume> lightVolumes;  ///< [triangle][light]
    std::vector<uint8_t> lightActive;          ///< [triangle][light]: in reach and not capped away
    std::vector<uint8_t> reached;              ///< [tile][triangle]: V_L met the tile's root box
    std::atomic<int> remaining{0};             ///< tiles that have not cast this chunk yet
    /// Held from publishing until the last tile has read every tile's reached flags: the slot is
    /// reused only after that, not as soon as remaining reaches 0.
    std::atomic<bool> inUse{false};

    /// @brief Bytes of one chunk of @p blockers blockers for @p lights lights, for memory planning
    /// (the per-tile reached flags are left out, so a plan does not depend on the thread count).
    static size_t bytes(size_t blockers, size_t lights) {
        return blockers * (sizeof(BlockerTriangle) + lights * (sizeof(PenumbraVolume) + 1));
    }
};

/// @brief The root culls of one cast: fixed once the receivers are known.
class BlockerCulls {
public:
    /// @param receivers the box around every receiver of the cast
    BlockerCulls(const LightSamples& samples, const CastOptions& options, const Box& receivers);

    /// @brief Prepares @p blockers into @p batch, in parallel (TBB, grain 256).
    /// @return how many closed-surface triangles were skipped as facing away from every light.
    uint64_t prepare(BlockerBatch& batch, std::span<const Triangle> blockers) const;

private:
    const LightSamples& samples_;
    const CastOptions& options_;
    Box receivers_;
    double receiversExtent_;  ///< largestCoordinate(receivers_), for every closed face's cutInFront()
    SimdLevel volumeLevel_;          ///< options_.simd resolved: which code builds V_L
    std::vector<LightReach> reach_;  ///< per light
};

/// @brief Appends to @p volume, V_L of the closed face @p t, the plane that culls every receiver
/// more than a margin in front of T, where the face blocks nothing (closed casters: a segment
/// from the light that reaches such a receiver through T leaves the solid there, and the face
/// where it entered blocks it). Its margin bounds TileCaster::inFrontOfClosed()'s over every box
/// inside @p receivers, so every box (or receiver) the plane culls, that test culls too, and the
/// traversal can skip that test per node: the plane leaves a box's active set once the box is
/// behind it.
/// @param receiversExtent largestCoordinate(@p receivers), computed once per cast by the caller
/// @return false when every receiver in @p receivers lies in front (T casts nothing); true
/// otherwise, also when the volume is full (frontCulled then stays false).
bool cutInFront(PenumbraVolume& volume, const BlockerTriangle& t, const Box& receivers, double receiversExtent,
                const CastOptions& options);

/// @brief Every vertex of @p bound strictly behind T's plane, beyond roundoff of the plane's
/// evaluation (for a sun, every direction of the cone points away from T's front side).
bool facesAway(const BlockerTriangle& t, const ConvexBound& bound);

}  // namespace penumbra
