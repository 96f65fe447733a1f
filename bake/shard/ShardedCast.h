#pragma once
/// @file ShardedCast.h
/// @brief The one object the pipeline asks about shards, merges and checkpoints (bake/Pipeline.cpp
/// holds one per bake): which blockers and receivers to cast, which tiles are restored, and what
/// to write instead of, or before, the outputs.

#include "bake/cast/Caster.h"
#include "bake/shard/Checkpoint.h"
#include "bake/shard/ShardRun.h"

#include <functional>
#include <memory>
#include <optional>
#include <span>

namespace penumbra {

/// @brief A bake's shard, merge and checkpoint state, made once the scan has found the receivers.
class ShardedCast {
public:
    /// @param methodKey every setting that changes the bits (BakeIdentity)
    /// @param memoryTiles whether the method casts memory tiles (CasterTraits; cutting by receivers needs it)
    /// @throw InputError for a cut the method cannot do, or an unreadable scene file.
    ShardedCast(const ShardSettings& settings, const std::string& sceneFile, const std::string& methodKey, bool memoryTiles,
                const ReceiverSet& receivers, const std::vector<uint32_t>& sampleSets, const LightSamples& samples,
                bool quiet);
    ~ShardedCast();

    /// True when the bake keeps every receiver's masks for this object (shard, merge, checkpoints).
    static bool keepsMasks(const ShardSettings& s) { return s.count > 0 || s.merge || !s.checkpointDir.empty(); }

    ShardCut cut() const { return cut_; }

    /// @brief Hooks for the caster's first pass: the shard's receivers, restored and finished tiles.
    /// @param masks every receiver's masks, filled by the sink as tiles finish
    /// @param restored called once per restored tile with its receivers, whose masks @p masks now
    ///        holds (to shade them)
    TileHooks tileHooks(VisibilityMasks& masks, std::function<void(std::span<const uint32_t>)> restored);

    /// @brief Writes the shard file of this bake (`--shard`).
    void writeShard(const VisibilityMasks& masks);

    /// @brief `penumbra merge`: ORs every shard file into @p masks. @return the shard count.
    uint32_t merge(VisibilityMasks& masks);

    /// @brief The bake's outputs are in place: its checkpoints are no longer needed.
    void complete() noexcept;

    /// @brief What is checkpointed on disk now, for the line of a stopped bake: "N memory
    /// tile(s)", and the progress of the tile in hand when it was saved.
    std::string checkpointedWork() const;

    /// @brief For the stats JSON (`"shard"`): the shard and cut, receivers cast, checkpointed
    /// tiles restored and written.
    nlohmann::json stats() const;

private:
    ShardSettings settings_;
    const ReceiverSet& receivers_;
    const LightSamples& samples_;
    BakeIdentity id_;
    ShardCut cut_ = ShardCut::Automatic;
    std::vector<uint8_t> present_;  ///< receivers this bake has cast or restored
    std::unique_ptr<Checkpoints> checkpoints_;
};

}  // namespace penumbra
