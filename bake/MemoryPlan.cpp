#include "bake/MemoryPlan.h"

#include "stream/util/Error.h"
#include "stream/util/Memory.h"

#include <algorithm>

namespace penumbra {

std::string budgetText(uint64_t bytes) { return fmt::format("{}M", (bytes + (1u << 20) - 1) >> 20); }

std::string refusedBudgetText(uint64_t bytes) {
    // Rounded to nearest, 102.8 MiB was "103 MiB is too small ...; at least 103M is needed".
    if (bytes < (1u << 20)) return formatBytes(bytes);
    if (bytes % (1u << 20) == 0) return fmt::format("{} MiB", bytes >> 20);
    const uint64_t tenths = bytes * 10 / (1u << 20);
    return fmt::format("{}.{} MiB", tenths / 10, tenths % 10);
}

uint64_t scanPhaseBytes(const MemoryDemand& d) {
    // The alpha table is built and the samples generated just before the scan reads anything:
    // their build peaks come first.
    return kBaselineBytes + d.alphaBytes + std::max({d.alphaBuildBytes, d.sampleBuildBytes, d.bufferBytes + d.scanBytes + d.sourceBytes});
}

uint64_t keptMaskBytes(const MemoryDemand& d) {
    if (!d.dumpMasks) return 0;
    const uint64_t row = 8ull * uint64_t(d.groups);
    if (d.maskRows == 0 || d.maskRows >= d.receivers) return d.receivers * row;
    return d.maskRows * row + d.receivers * sizeof(uint32_t);
}

MemoryPlan planMemory(const MemoryDemand& d, uint64_t budget, const std::string& label, uint64_t overhead,
                      uint64_t namedSlack) {
    MemoryPlan plan;
    plan.budget = budget;
    // Resident for the whole bake, per receiver: the receiver set (position, normal, pixel, depth:
    // 32 bytes), its sample set (4), its results (visibility 4, irradiance 12) and its place in
    // the id list and the tile partition (8). Then the masks kept whole, if any.
    const uint64_t residentPerReceiver = 32 + 4 + 16 + 8;
    plan.residentBytes =
        kBaselineBytes + d.bufferBytes + d.sampleBytes + d.kindBytes + d.methodBytes + d.alphaBytes + d.translucentBytes +
        d.receivers * residentPerReceiver + keptMaskBytes(d);
    // The scan pass holds what the receiver kind needs (a camera's z-buffer and the receiver set
    // it makes, as the kind reports) and the sources; that is freed before casting starts. The
    // bucket pass reads the sources again with everything resident.
    const uint64_t bucketPhase = plan.residentBytes + d.sourceBytes;
    const uint64_t castSources = d.sourceDuringCast ? d.sourceBytes : 0;
    // In a tile, per live receiver: double position 24, epsilon 8, id/set/mask slot 12, umbra
    // 1 + 8 * umbraWords, about one node per 4 receivers (32 bytes + bits), and in the worst case a
    // mask of one word per group. While a tile's hierarchy is built, the split into sub-tiles (8)
    // exists on top, and one at a time: the inputs (40 bytes), the build's items and order
    // (32 + 4; ReceiverHierarchy::buildNodes()), the order and one permuted array (4 + 8 at
    // most). 40 + 4 + 24, the allowance from before the items, covers each.
    plan.perReceiverBytes = 24 + 8 + 12 + 1 + 8ull * d.umbraWords + (32 + 1 + 8ull * d.umbraWords) / 4 + 8ull * d.groups +
                            40 + 4 + 24 + 8;
    // Tiles cut the receivers cast, which for a by-receivers shard are its share only (cut as if
    // it held them all, shard 0 of 4 took 32 tiles where the whole bake took 5).
    const uint64_t cast = d.castReceivers ? std::min(d.castReceivers, d.receivers) : d.receivers;
    const uint64_t smallestTile = std::min<uint64_t>(std::max<uint64_t>(cast, 1), kMinimumTileReceivers);
    const uint64_t outputPhase = plan.residentBytes + d.outputBytes;
    // Each sub-tile's fixed state (one sub-tile per thread at least) comes on top of a tile's receivers.
    auto fixedOf = [&](int perThread) { return subTilesAtOnce(d.threads, perThread) * d.subTileBytes; };
    plan.minimumBudget = std::max({scanPhaseBytes(d), bucketPhase, outputPhase,
                                   plan.residentBytes + castSources + fixedOf(1) + smallestTile * plan.perReceiverBytes});
    if (d.refinement.addedReceivers > 0) {
        MemoryDemand after = d;
        after.refinement = {};
        after.receivers += d.refinement.addedReceivers;
        after.kindBytes = d.refinement.kindBytesAfter;
        after.outputBytes = d.refinement.outputBytesAfter;
        plan.minimumBudget = std::max(plan.minimumBudget, planMemory(after, 0).minimumBudget);
    }
    if (budget == 0) return plan;
    if (budget < plan.minimumBudget) {
        std::string why;
        if (!d.sourceDetail.empty() && d.sourceBytes > plan.minimumBudget / 2) why = fmt::format(" ({})", d.sourceDetail);
        else if (d.refinement.addedReceivers > 0)
            why = fmt::format(" (with the antialiasing pass's up to {} more receivers)", d.refinement.addedReceivers);
        throw InputError(fmt::format("{} {} is too small for {} receivers of {} light-sample groups each; at least {} is needed{}", label,
                                     refusedBudgetText(budget + overhead), d.receivers, d.groups,
                                     budgetText(plan.minimumBudget + overhead + namedSlack), why));
    }
    const uint64_t room = budget - plan.residentBytes - castSources;
    while (plan.subTilesPerThread > 1 && fixedOf(plan.subTilesPerThread) > room / 2) plan.subTilesPerThread /= 2;
    const uint64_t perTile = (room - std::min(room, fixedOf(plan.subTilesPerThread))) / plan.perReceiverBytes;
    plan.tiles = int(std::max<uint64_t>(1, (cast + perTile - 1) / std::max<uint64_t>(perTile, 1)));
    // The refinement's receivers come later, into what is spare now: leave it to them.
    const uint64_t castPeak = fixedOf(plan.subTilesPerThread) + (cast + uint64_t(plan.tiles) - 1) / uint64_t(plan.tiles) * plan.perReceiverBytes;
    if (d.refinement.addedReceivers == 0 && room > castPeak && budget > outputPhase)
        plan.spareBytes = std::min(room - castPeak, budget - outputPhase);
    return plan;
}

}  // namespace penumbra
