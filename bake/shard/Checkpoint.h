#pragma once
/// @file Checkpoint.h
/// @brief Resume after a kill (`--checkpoint DIR`, `--resume DIR`): every finished memory tile of
/// the first cast pass is written as a partial file (PartialFile.h) named by the tile, and a bake
/// started again with the same command restores the tiles it finds instead of casting them.
///
/// A tile's masks are final once the tile is cast (every blocker has been replayed against it),
/// so a restored tile gives exactly the bits a cast would: the outputs are byte-identical to an
/// uninterrupted bake. A file of another scene, other settings, another tiling or another format
/// version is never used: `--checkpoint` ignores it with a note, `--resume` refuses it. The
/// checkpoints are removed once the bake's outputs are in place.

#include "bake/shard/ShardRun.h"

#include <span>
#include <string>
#include <vector>

namespace penumbra {

/// @brief The checkpoint directory of one bake.
class Checkpoints {
public:
    /// @param settings the bake's shard settings: checkpointDir, resume, and the shard it casts
    /// @param header the bake's identity (hashes, cut, receivers, groups); part and parts are set per tile
    Checkpoints(const ShardSettings& settings, PartialHeader header, const LightSamples& samples, bool quiet);

    /// @brief Restores tile @p tile of @p tiles (receivers @p ids) into @p masks when its
    /// checkpoint exists and matches. @return whether it did.
    /// @throw InputError for a mismatched or damaged checkpoint under `--resume`.
    bool restore(size_t tile, size_t tiles, std::span<const uint32_t> ids, VisibilityMasks& masks);

    /// @brief Writes tile @p tile's checkpoint from @p masks, atomically.
    /// @throw InputError naming the file (a full disk, an unwritable directory).
    void save(size_t tile, size_t tiles, std::span<const uint32_t> ids, const VisibilityMasks& masks);

    /// @brief Removes every checkpoint this bake wrote or restored (the bake is complete).
    void removeAll() noexcept;

    /// Tiles restored and written so far.
    size_t restored() const { return restored_; }
    size_t saved() const { return saved_; }

private:
    std::string pathOf(size_t tile, size_t tiles) const;
    void reject(const std::string& path, const std::string& why);

    ShardSettings settings_;
    PartialHeader header_;
    const LightSamples& samples_;
    bool quiet_;
    std::vector<std::string> written_;
    size_t restored_ = 0, saved_ = 0;
    long killAfter_ = -1;  ///< PENUMBRA_TEST_KILL_AFTER_TILES: SIGKILL itself after that many saves (tests)
};

}  // namespace penumbra
