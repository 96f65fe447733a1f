// Partial files (.pnpart): shard files and checkpoints (bake/shard/PartialFile.h). The reader, then
// what a merge or a resume does with a file it accepts: the shard checks of a merge, and the OR of
// its masks into a bake's masks sized as its header says.
#include "FuzzSupport.h"

#include "bake/shard/ShardFiles.h"

#include <algorithm>

namespace {

/// Light samples of @p groups groups, of varied sizes (1..64 samples), for the full-umbra masks.
penumbra::LightSamples samplesOf(uint32_t groups) {
    penumbra::LightSamples samples;
    uint32_t first = 0;
    for (uint32_t k = 0; k < groups; ++k) {
        penumbra::LightSampleGroup g;
        g.first = first, g.count = 1 + (k * 37) % 64;
        first += g.count;
        samples.groups.push_back(g);
    }
    return samples;
}

}  // namespace

PENUMBRA_FUZZ_FILE("shard-0-of-1.pnpart") {
    using namespace penumbra;
    const PartialFile file = readPartialFile(path);
    const PartialHeader& h = file.header;
    // A bake holds receivers x groups words; past 2^22 the harness would test the allocator.
    if (h.receivers * std::max<uint64_t>(h.groups, 1) > (uint64_t(1) << 22) || h.groups == 0) return;
    const LightSamples samples = samplesOf(h.groups);
    VisibilityMasks masks(size_t(h.receivers), int(h.groups));
    std::vector<uint8_t> covered(size_t(h.receivers), 0);
    addPartialMasks(file, samples, masks, covered);
    // The merge of the directory that holds it, as a bake of what its header claims (the settings
    // hash cannot be matched, so the merge refuses it there, after its other checks).
    BakeIdentity id{h.sceneHash, 0, h.contentHash};
    VisibilityMasks merged(size_t(h.receivers), int(h.groups));
    try {
        mergeShardFiles(fuzz::scratchDir(), id, samples, merged);
    } catch (const InputError&) {
    }
    // A tree merge's inner node: combine needs no scene, so a shard file gets through every check
    // and is written again (into a folder of its own, which the next run overwrites).
    if (h.role == PartialHeader::kShard) combineShardFiles({path}, std::nullopt, fuzz::scratchDir() + "/combined");
}
