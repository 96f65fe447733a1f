#pragma once
/// @file ShardRun.h
/// @brief The pieces a sharded bake and `penumbra merge` are made of: the bake's identity in
/// partial files, the cut of receivers or blockers, and the checks of a merge.
///
/// Masks are an OR over blockers and receivers are independent, so:
///  - by receivers, shard I casts the I-th of N spatial parts of the receivers (the same median
///    splits as memory tiles, PenumbraCaster.h); its masks are final for those receivers;
///  - by blockers, shard I casts the I-th of N interleaved shares of the blocker stream (blocks
///    of the source's stream dealt out in turn, stream/BlockCyclicSource.h) against every
///    receiver, and generates or reads only its share where the source can skip; the merge ORs
///    the masks.
/// Either way the merge shades the complete masks once, the way an unsharded bake does, so its
/// outputs are byte-identical.

#include "bake/cast/VisibilityMasks.h"
#include "bake/light/Light.h"
#include "bake/shard/PartialFile.h"
#include "bake/shard/ShardSettings.h"
#include "receivers/ReceiverSet.h"
#include "stream/BlockCyclicSource.h"

#include <optional>
#include <string>
#include <vector>

namespace penumbra {

/// @brief Fewest receivers per shard for the automatic cut to choose receivers.
inline constexpr size_t kMinReceiversPerShard = 4096;

/// @brief The cut a bake of @p receivers receivers in @p shards shards uses: @p cut itself, or for
/// Automatic, receivers when each shard gets at least kMinReceiversPerShard of them and the
/// method casts memory tiles (@p tiles: hpc, the only one that can cut by receivers), else blockers.
ShardCut resolveShardCut(ShardCut cut, size_t receivers, uint32_t shards, bool tiles);

/// @brief What identifies one bake in its partial files, whatever the shard.
struct BakeIdentity {
    uint64_t sceneHash = 0;    ///< the scene file's bytes
    uint64_t methodHash = 0;   ///< the method and the options that change bits
    uint64_t contentHash = 0;  ///< receivers, sample sets, light samples

    /// The settings hash of a part of a bake cut by @p cut into @p parts shards.
    uint64_t settingsHash(ShardCut cut, uint32_t shards) const;
};

/// @brief Hashes what a partial file must match. @p methodKey is every setting that changes bits
/// (the method's name, its filters).
/// @throw InputError when the scene file cannot be read.
BakeIdentity bakeIdentity(const std::string& sceneFile, const std::string& methodKey, const ReceiverSet& receivers,
                          const std::vector<uint32_t>& sampleSets, const LightSamples& samples);

/// @brief `DIR/shard-I-of-N.pnpart`.
std::string shardFilePath(const std::string& dir, uint32_t index, uint32_t count);

/// @brief The receivers of shard @p index of @p count among @p ids (by-receivers cut).
std::vector<uint32_t> shardReceivers(const ReceiverSet& receivers, const std::vector<uint32_t>& ids, uint32_t index,
                                     uint32_t count);

/// @brief The receivers a by-receivers shard casts (its share, in id order), or nullopt when the
/// bake casts every receiver (not a casting shard, one shard, or cut by blockers). @p tiles as for
/// resolveShardCut(); a cut by receivers without tiles is ShardedCast's error, not decided here.
std::optional<std::vector<uint32_t>> receiverShareOf(const ShardSettings& settings, const ReceiverSet& receivers, bool tiles);

/// @brief N when the bake is shard I of N cut by receivers by its settings alone (`--shard-by
/// receivers`, a method with tiles), else 1. The median splits give every part at most
/// ceil(receivers / N), which bounds the share before the scan has placed the receivers; an
/// automatic cut is decided by the receivers the scan finds (receiverShareOf()).
uint32_t receiverSharesBeforeScan(const ShardSettings& settings, bool tiles);

/// @brief Which share of the blocker stream a by-blockers shard casts (stream/BlockCyclicSource.h),
/// or nullopt when the bake casts every blocker (not a shard, cut by receivers, or one shard).
/// The block size follows from @p triangles, the whole stream's count, the same in every shard.
/// @p tiles as for resolveShardCut().
std::optional<BlockShare> blockerShareOf(const ShardSettings& settings, size_t receivers, uint64_t triangles, bool tiles);

/// @brief Writes shard @p settings.index's file: the masks of the receivers marked in @p present.
/// @throw InputError naming the file.
void writeShardFile(const ShardSettings& settings, ShardCut cut, const BakeIdentity& id, const LightSamples& samples,
                    const VisibilityMasks& masks, std::span<const uint8_t> present);

}  // namespace penumbra
