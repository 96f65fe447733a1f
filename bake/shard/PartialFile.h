#pragma once
/// @file PartialFile.h
/// @brief The binary format of partial results: shard files (`--shard`) and checkpoints
/// (`--checkpoint`). docs/distributed.md, "Shard file format", describes it byte by byte.
///
/// A partial file holds the blocked masks of some receivers of one bake, before shading: the
/// shading is done once, by whoever writes the outputs, from masks that are complete, so a merged
/// bake shades exactly the bits an unsharded one does. Each receiver has a 2-bit state (absent,
/// clear, partial, full umbra), packed four to a byte; only partial receivers store their mask
/// words. A header names the bake (scene hash, settings hash, receiver content hash, format
/// version) and the part (shard I of N, or memory tile T of M); a checksum trailer makes a
/// truncated or damaged file an error rather than a silent hole.

#include "bake/cast/VisibilityMasks.h"
#include "bake/light/Light.h"

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

/// 3: the header names a range of shards (a combined file of a tree merge covers several) and
/// the replay position of a tile in progress.
inline constexpr uint32_t kPartialFormatVersion = 3;

/// @brief What a partial file is a part of.
struct PartialHeader {
    uint32_t version = kPartialFormatVersion;
    uint32_t role = 0;          ///< 1: a shard file, 2: a checkpointed memory tile, 3: a tile in progress
    uint64_t sceneHash = 0;     ///< the scene file's bytes
    uint64_t settingsHash = 0;  ///< method, cut, shard count and the options that change bits
    uint64_t contentHash = 0;   ///< receivers, sample sets and light samples, after the scan
    uint32_t cut = 0;           ///< ShardCut
    uint32_t part = 0, parts = 0;  ///< shard I of N, or tile T of M
    /// The end (exclusive) of the shards the file covers, [part, partEnd): more than part + 1 for
    /// a combined file (`penumbra combine`); 0 when writing means part + 1. Read back, always set.
    uint32_t partEnd = 0;
    /// A tile in progress: its masks hold the first `replayed` blockers of the largest-first
    /// replay, whose bytes hash to `replayHash` (0 and 0 for the other roles).
    uint64_t replayed = 0, replayHash = 0;
    uint64_t receivers = 0;
    uint32_t groups = 0;        ///< mask words per receiver
    std::vector<uint32_t> lightFirstGroup;  ///< per-light data: groups of light i are [f[i], f[i+1])

    static constexpr uint32_t kShard = 1, kCheckpoint = 2, kTileProgress = 3;
};

/// @brief A receiver's state in a partial file.
enum class ReceiverState : uint8_t { Absent = 0, Clear = 1, Partial = 2, Full = 3 };

/// @brief Writes the masks of the receivers marked in @p present (one byte per receiver, 0 or 1)
/// to @p path atomically and durably (AtomicFile, fsync of the data before its name is linked and
/// of the directory after). A receiver whose words equal its groups' full masks is
/// stored as full umbra, one with no bit as clear.
/// @throw InputError naming @p path.
void writePartialFile(const std::string& path, const PartialHeader& header, const LightSamples& samples,
                      const VisibilityMasks& masks, std::span<const uint8_t> present);

/// @brief Writes receivers with explicit @p states (ReceiverState, one per receiver) and, for the
/// partial ones, their rows of @p masks: what a combined file holds, whose states come from the
/// files it combines.
/// @throw InputError naming @p path.
void writePartialStates(const std::string& path, const PartialHeader& header, std::span<const uint8_t> states,
                        const VisibilityMasks& masks);

/// @brief A partial file read back and checked against its own checksum.
struct PartialFile {
    std::string path;
    PartialHeader header;
    std::vector<uint8_t> state;   ///< ReceiverState per receiver, unpacked
    std::vector<uint64_t> words;  ///< groups words per partial receiver, in receiver order
};

/// @brief Reads @p path whole.
/// @throw InputError "PATH: truncated ..." / "not a penumbra partial file" / "format version ..." /
/// "checksum mismatch" for every file that is not exactly what writePartialFile() wrote.
PartialFile readPartialFile(const std::string& path);

/// @brief Reads the header of @p path only (its states and masks are not read, nor checked).
/// @throw InputError as readPartialFile() does for a header that is not one.
PartialHeader readPartialHeader(const std::string& path);

/// @brief ORs @p file's masks into @p masks (full umbra as the groups' full masks) and marks
/// the receivers it holds in @p covered (a count per receiver).
void addPartialMasks(const PartialFile& file, const LightSamples& samples, VisibilityMasks& masks,
                     std::vector<uint8_t>& covered);

/// @brief 64-bit FNV-1a, for the header's hashes and the trailer's checksum.
struct Fnv64 {
    uint64_t value = 0xcbf29ce484222325ull;
    void add(const void* data, size_t bytes);
    template <class T>
    void addValue(const T& v) { add(&v, sizeof v); }
};

}  // namespace penumbra
