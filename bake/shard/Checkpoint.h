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
/// checkpoints are removed once the bake's outputs are in place, and the folder with them when it
/// is left empty.
///
/// Within a tile, every `--checkpoint-every` seconds of cast (and on SIGTERM) the tile's masks so
/// far are saved as `STEM-HASH.tile-T-of-M.progress.pnpart` (the scene file's stem and a hash of its
/// path; a shard's names add `shard-I-of-N.`), with the position in the replay they hold; a
/// resume restores them and casts only the rest of the replay (HpcCaster, TileProgress).

#include "bake/cast/Caster.h"
#include "bake/shard/ShardRun.h"
#include "stream/util/Timer.h"

#include <optional>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

/// @brief What every checkpoint file of a bake of @p sceneFile starts with: "STEM-HASH." (the
/// file's stem and a hash of its absolute path), then "shard-I-of-N." for a shard.
std::string checkpointNamePrefix(const std::string& sceneFile, const ShardSettings& settings);

/// @brief The checkpoint directory of one bake.
class Checkpoints {
public:
    /// @param settings the bake's shard settings: checkpointDir, resume, and the shard it casts
    /// @param header the bake's identity (hashes, cut, receivers, groups); part and parts are set per tile
    /// @param sceneFile names the checkpoints (namePrefix()), so that bakes of other scene files
    ///        may share the folder
    Checkpoints(const ShardSettings& settings, PartialHeader header, const LightSamples& samples, bool quiet,
                const std::string& sceneFile = "");
    /// Removes the folder when this bake made it and it is still empty (a bake refused after it
    /// was opened, such as for translucent blockers, leaves no folder behind).
    ~Checkpoints();
    Checkpoints(const Checkpoints&) = delete;
    Checkpoints& operator=(const Checkpoints&) = delete;

    /// @brief Restores tile @p tile of @p tiles (receivers @p ids) into @p masks when its
    /// checkpoint exists and matches. @return whether it did.
    /// @throw InputError for a mismatched or damaged checkpoint under `--resume`.
    bool restore(size_t tile, size_t tiles, std::span<const uint32_t> ids, VisibilityMasks& masks);

    /// @brief Writes tile @p tile's checkpoint from @p masks, atomically.
    /// @throw InputError naming the file (a full disk, an unwritable directory).
    void save(size_t tile, size_t tiles, std::span<const uint32_t> ids, const VisibilityMasks& masks);

    /// @brief The saved progress of tile @p tile when it exists and matches, its masks in the
    /// order of @p ids; restarts the `--checkpoint-every` clock (the tile's cast begins).
    /// @throw InputError for a mismatched or damaged one under `--resume`.
    std::optional<TileProgress> resumeTile(size_t tile, size_t tiles, std::span<const uint32_t> ids);

    /// Chunks of the replay after which a tile's progress is saved whatever the clock says, so a
    /// fast machine with a long `--checkpoint-every` still saves every 64M blockers or so.
    static constexpr uint64_t kChunksPerCheckpoint = 16384;

    /// @brief Asked once per chunk cast: true when `--checkpoint-every` seconds or
    /// kChunksPerCheckpoint chunks have passed since the tile began or was last saved.
    bool progressDue() { return ++chunksSinceSave_ >= kChunksPerCheckpoint || progressClock_.seconds() >= settings_.checkpointEvery; }

    /// @brief Writes tile @p tile's progress (the rows of @p ids in @p masks, after @p replayed
    /// blockers hashing to @p replayHash), atomically, over the previous one.
    /// @throw InputError naming the file.
    void saveProgress(size_t tile, size_t tiles, std::span<const uint32_t> ids, const VisibilityMasks& masks,
                      uint64_t replayed, uint64_t replayHash);

    /// @brief The replay did not match tile @p tile's progress: an error under `--resume`, else a note.
    /// @throw InputError under `--resume`.
    void rejectProgress(size_t tile, size_t tiles);

    /// @brief Looks once for this bake's checkpoints of another tile count than @p tiles: an error
    /// under `--resume`, else one note, and they are removed with this bake's own. This bake's
    /// checkpoints of @p tiles tiles named after another path of the scene file (it was moved
    /// since) are renamed to this bake's names, with a note.
    /// @throw InputError naming the first such file under `--resume`.
    void checkOtherTilings(size_t tiles);

    /// @brief Removes every checkpoint this bake wrote or restored (the bake is complete), then
    /// the checkpoint folder if nothing else is left in it.
    void removeAll() noexcept;

    /// Tiles restored and written so far.
    size_t restored() const { return restored_; }
    size_t saved() const { return saved_; }
    /// Tiles resumed from a saved progress, the blockers they skipped, and progress saves.
    size_t resumed() const { return resumed_; }
    uint64_t skipped() const { return skipped_; }
    size_t progressSaves() const { return progressSaves_; }
    /// True when the tile in hand has its progress on disk (saved, and not yet superseded by the whole tile).
    bool progressPending() const { return progressPending_; }

private:
    std::string pathOf(size_t tile, size_t tiles, const char* suffix = "") const;
    /// "STEM-HASH." naming the scene file, then "shard-I-of-N." for a shard's checkpoints.
    std::string namePrefix() const { return namePrefix_; }
    /// Makes the folder again when another bake's end removed it.
    void ensureFolder() const;
    void reject(const std::string& path, const std::string& why);
    /// Whether @p path's header is this bake's (scene, settings, content); false when unreadable.
    bool sameBake(const std::string& path) const;
    bool isThisBake(const PartialHeader& h) const {
        return h.sceneHash == header_.sceneHash && h.settingsHash == header_.settingsHash && h.contentHash == header_.contentHash;
    }
    /// Why a file of this bake named tile @p tile of @p tiles holds another tile; empty when not.
    static std::string misnamedWhy(const PartialHeader& h, size_t tile, size_t tiles);
    /// --resume: reject()s @p path, named tile @p tile of @p tiles, if it is this bake's file of
    /// another tile (checked for every file before the first tile is cast).
    void checkName(const std::string& path, size_t tile, size_t tiles);
    /// Renames each (from, to) of checkOtherTilings(): this bake's files under another scene path.
    void adoptMoved(std::vector<std::pair<std::string, std::string>> moved);
    /// @brief Reads @p path if it exists and checks that it is a @p role file of this bake and
    /// of tile @p tile of @p tiles, holding exactly @p ids; a mismatch is reject()ed.
    /// @return the file, or nullopt.
    std::optional<PartialFile> readMatching(const std::string& path, uint32_t role, size_t tile, size_t tiles,
                                            std::span<const uint32_t> ids);

    ShardSettings settings_;
    bool madeFolder_ = false;  ///< the constructor created settings_.checkpointDir
    PartialHeader header_;
    const LightSamples& samples_;
    bool quiet_;
    std::string namePrefix_;
    std::vector<std::string> written_;
    size_t restored_ = 0, saved_ = 0, resumed_ = 0, progressSaves_ = 0;
    uint64_t skipped_ = 0, lastSkipped_ = 0;
    bool progressPending_ = false;
    bool tilingChecked_ = false;
    Stopwatch progressClock_;
    uint64_t chunksSinceSave_ = 0;  ///< chunks cast since the tile began or was last saved
    long killAfter_ = -1;  ///< PENUMBRA_TEST_KILL_AFTER_TILES: SIGKILL itself after that many saves (tests)
};

}  // namespace penumbra
