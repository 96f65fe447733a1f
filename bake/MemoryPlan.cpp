#include "bake/MemoryPlan.h"

#include "stream/Error.h"
#include "stream/Memory.h"

#include <algorithm>

namespace penumbra {

MemoryPlan planMemory(const MemoryDemand& d, uint64_t budget) {
    MemoryPlan plan;
    plan.budget = budget;
    // Resident for the whole bake, per receiver: the receiver set (position, normal, pixel, depth:
    // 32 bytes), its sample set (4), its results (visibility 4, irradiance 12) and its place in
    // the id list and the tile partition (8).
    const uint64_t residentPerReceiver = 32 + 4 + 16 + 8 + (d.dumpMasks ? 8ull * d.groups : 0);
    plan.residentBytes =
        kBaselineBytes + d.bufferBytes + d.sampleBytes + d.kindBytes + d.sceneBytes + d.receivers * residentPerReceiver;
    // The scan pass holds what the receiver kind needs (a camera's z-buffer and the receiver set
    // it makes, as the kind reports); that is freed before casting starts.
    const uint64_t passBytes = kBaselineBytes + d.bufferBytes + d.scanBytes;
    // In a tile, per live receiver: double position 24, epsilon 8, id/set/mask slot 12, umbra
    // 1 + 8 * umbraWords, about one node per 4 receivers (32 bytes + bits), and in the worst case a
    // mask of one word per group. While a tile's hierarchy is built, its inputs (40 bytes), the
    // build order (4), one permuted array copy (24) and the split into sub-tiles (8) exist on top.
    plan.perReceiverBytes = 24 + 8 + 12 + 1 + 8ull * d.umbraWords + (32 + 1 + 8ull * d.umbraWords) / 4 + 8ull * d.groups +
                            40 + 4 + 24 + 8;
    const uint64_t smallestTile = std::min<uint64_t>(std::max<uint64_t>(d.receivers, 1), kMinimumTileReceivers);
    const uint64_t outputPhase = plan.residentBytes + d.outputBytes;
    plan.minimumBudget = std::max({passBytes, outputPhase, plan.residentBytes + smallestTile * plan.perReceiverBytes});
    if (budget == 0) return plan;
    if (budget < plan.minimumBudget)
        throw InputError(fmt::format("--memory-budget {} is too small for {} receivers with {} mask words each; at least {} is needed",
                                     formatBytes(budget), d.receivers, d.groups, formatBytes(plan.minimumBudget)));
    const uint64_t perTile = (budget - plan.residentBytes) / plan.perReceiverBytes;
    plan.tiles = int(std::max<uint64_t>(1, (d.receivers + perTile - 1) / std::max<uint64_t>(perTile, 1)));
    return plan;
}

}  // namespace penumbra
