#pragma once
/// @file ShardSettings.h
/// @brief How a bake takes part in a distributed or resumable run: which shard it casts
/// (`--shard I/N`, `--shard-by`), whether it merges shard files (`penumbra merge`), and where its
/// checkpoints go (`--checkpoint`, `--resume`). docs/distributed.md says how they fit together.

#include <cstdint>
#include <string>

namespace penumbra {

/// @brief How a sharded bake is cut.
enum class ShardCut : uint32_t {
    Automatic = 0,  ///< receivers when there are enough of them to cut, else blockers
    Receivers = 1,  ///< shard I casts every blocker against a spatial 1/N of the receivers
    Blockers = 2,   ///< shard I casts the I-th of N interleaved shares of the blockers against all receivers
};

/// @brief The shard, merge and checkpoint part of a bake's settings.
struct ShardSettings {
    uint32_t index = 0;  ///< I of `--shard I/N`
    uint32_t count = 0;  ///< N of `--shard I/N`; 0: not sharded
    ShardCut cut = ShardCut::Automatic;
    std::string dir;            ///< where shard files are written (bake) or read (merge)
    bool merge = false;         ///< combine the shard files of `dir` into the normal outputs
    std::string checkpointDir;  ///< one file per finished memory tile; empty: no checkpoints
    bool resume = false;        ///< `--resume`: a checkpoint that does not match is an error, not a note
    double checkpointEvery = 300;  ///< `--checkpoint-every`: seconds of cast between checkpoints within a tile

    /// True when this bake casts one shard and writes a shard file instead of the outputs.
    bool casting() const { return count > 0 && !merge; }
};

/// @brief Parses `I/N` (0 <= I < N <= 65536).
/// @throw InputError naming @p option.
void parseShardSpec(const std::string& text, const std::string& option, ShardSettings& out);

/// @brief Parses `receivers`, `blockers` or `auto`.
/// @throw InputError naming @p option.
ShardCut parseShardCut(const std::string& text, const std::string& option);

/// @brief "receivers", "blockers" or "auto".
const char* shardCutName(ShardCut cut);

}  // namespace penumbra
