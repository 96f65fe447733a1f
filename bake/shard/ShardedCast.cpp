#include "bake/shard/ShardedCast.h"

#include "bake/shard/ShardFiles.h"
#include "stream/util/Error.h"

#include <algorithm>

namespace penumbra {

ShardedCast::ShardedCast(const ShardSettings& settings, const std::string& sceneFile, const std::string& methodKey,
                         bool memoryTiles, const ReceiverSet& receivers, const std::vector<uint32_t>& sampleSets,
                         const LightSamples& samples, bool quiet)
    : settings_(settings), receivers_(receivers), samples_(samples),
      id_(bakeIdentity(sceneFile, methodKey, receivers, sampleSets, samples)) {
    if (settings_.casting()) {
        cut_ = resolveShardCut(settings_.cut, receivers.size(), settings_.count, memoryTiles);
        if (cut_ == ShardCut::Receivers && !memoryTiles)
            fail("--shard-by", "receivers needs a method that casts memory tiles (--method hpc); use --shard-by blockers");
    }
    // By blockers every receiver is cast; by receivers the tiles say which (tileHooks).
    present_.assign(receivers.size(), cut_ == ShardCut::Receivers ? 0 : 1);
    if (settings_.checkpointDir.empty() || settings_.merge) return;
    PartialHeader h;
    h.sceneHash = id_.sceneHash, h.contentHash = id_.contentHash, h.cut = uint32_t(cut_);
    Fnv64 shard;  // a shard's checkpoints are its own
    shard.addValue(id_.settingsHash(cut_, settings_.count)), shard.addValue(settings_.index);
    h.settingsHash = shard.value;
    h.receivers = receivers.size(), h.groups = uint32_t(samples.groupCount());
    h.lightFirstGroup = samples.lightFirstGroup;
    checkpoints_ = std::make_unique<Checkpoints>(settings_, std::move(h), samples, quiet, sceneFile);
}

ShardedCast::~ShardedCast() = default;

TileHooks ShardedCast::tileHooks(VisibilityMasks& masks, std::function<void(std::span<const uint32_t>)> restored) {
    TileHooks hooks;
    if (settings_.casting() && cut_ == ShardCut::Receivers)
        hooks.select = [this](std::vector<uint32_t> ids) {
            return shardReceivers(receivers_, ids, settings_.index, settings_.count);
        };
    hooks.restore = [this, &masks, restored](size_t tile, size_t tiles, std::span<const uint32_t> ids) {
        if (!checkpoints_ || !checkpoints_->restore(tile, tiles, ids, masks)) return false;
        for (uint32_t r : ids) present_[r] = 1;
        restored(ids);
        return true;
    };
    hooks.finished = [this, &masks](size_t tile, size_t tiles, std::span<const uint32_t> ids) {
        for (uint32_t r : ids) present_[r] = 1;
        if (checkpoints_) checkpoints_->save(tile, tiles, ids, masks);
    };
    if (!checkpoints_) return hooks;
    Checkpoints& c = *checkpoints_;
    hooks.resume = [&c](size_t tile, size_t tiles, std::span<const uint32_t> ids) { return c.resumeTile(tile, tiles, ids); };
    hooks.progressDue = [&c] { return c.progressDue(); };
    // The tile's rows of the bake's masks hold its progress while it is written; the tile's
    // finish overwrites them with its final masks.
    hooks.saveProgress = [&c, &masks](size_t tile, size_t tiles, std::span<const uint32_t> ids, const TileProgress& p) {
        for (size_t i = 0; i < ids.size(); ++i) std::copy_n(p.masks.row(i), masks.groups, masks.row(ids[i]));
        c.saveProgress(tile, tiles, ids, masks, p.replayed, p.replayHash);
    };
    hooks.rejectProgress = [&c](size_t tile, size_t tiles) { c.rejectProgress(tile, tiles); };
    return hooks;
}

void ShardedCast::writeShard(const VisibilityMasks& masks) {
    writeShardFile(settings_, cut_, id_, samples_, masks, present_);
}

uint32_t ShardedCast::merge(VisibilityMasks& masks) { return mergeShardFiles(settings_.dir, id_, samples_, masks); }

nlohmann::json ShardedCast::stats() const {
    nlohmann::json s = nlohmann::json::object();
    if (settings_.casting())
        s["index"] = settings_.index, s["count"] = settings_.count, s["cut"] = shardCutName(cut_);
    s["merge"] = settings_.merge;
    size_t cast = 0;
    for (uint8_t p : present_) cast += p;
    s["receivers_in_shard"] = settings_.merge ? receivers_.size() : cast;
    s["tiles_restored"] = checkpoints_ ? checkpoints_->restored() : 0;
    s["tiles_checkpointed"] = checkpoints_ ? checkpoints_->saved() : 0;
    s["tiles_resumed_in_progress"] = checkpoints_ ? checkpoints_->resumed() : 0;
    s["replay_skipped_triangles"] = checkpoints_ ? checkpoints_->skipped() : 0;
    s["progress_checkpoints"] = checkpoints_ ? checkpoints_->progressSaves() : 0;
    return s;
}

std::string ShardedCast::checkpointedWork() const {
    if (!checkpoints_) return "0 memory tiles";
    std::string work = fmt::format("{} memory tile(s)", checkpoints_->restored() + checkpoints_->saved());
    if (checkpoints_->progressPending()) work += " and the progress of the tile in hand";
    return work;
}

void ShardedCast::complete() noexcept {
    if (checkpoints_) checkpoints_->removeAll();
}

}  // namespace penumbra
