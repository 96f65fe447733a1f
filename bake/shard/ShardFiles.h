#pragma once
/// @file ShardFiles.h
/// @brief Sets of shard files: the merge that turns them into a bake's masks, and the combine
/// that turns several into one (an inner node of a tree merge, docs/distributed.md).
///
/// Every shard file covers a range of the N shards, [part, partEnd): one shard for a file that
/// `bake --shard` wrote, several for one that `penumbra combine` wrote. A set of files is one
/// bake's when they agree on the scene, the settings and the receivers, and their ranges never
/// overlap. Masks are an OR over blockers and receivers are independent, so combining is
/// associative: any tree of combines ends in the masks one merge of every shard would give.

#include "bake/cast/VisibilityMasks.h"
#include "bake/light/Light.h"
#include "bake/shard/ShardRun.h"

#include <optional>
#include <string>
#include <vector>

namespace penumbra {

/// @brief Shards [first, end) of a bake, as `penumbra combine --range A-B` names them (B inclusive).
struct ShardRange {
    uint32_t first = 0, end = 0;
};

/// @brief Parses `A-B` (shards A to B inclusive, A <= B < 65536).
/// @throw InputError naming @p option.
ShardRange parseShardRange(const std::string& text, const std::string& option);

/// @brief `DIR/shards-A-B-of-N.pnpart`: a combined file of shards A to B (inclusive).
std::string combinedFilePath(const std::string& dir, ShardRange range, uint32_t count);

/// @brief Reads every shard file of @p dir, checks that they are the N shards of this bake, each
/// covered once, complete, and ORs them into @p masks (sized for every receiver).
/// @return the number of shards merged.
/// @throw InputError (one line) for shards of another scene or settings, a missing shard, a
/// duplicate or overlapping file, a truncated or damaged file, or receivers no shard (or two) cast.
uint32_t mergeShardFiles(const std::string& dir, const BakeIdentity& id, const LightSamples& samples,
                         VisibilityMasks& masks);

/// @brief `penumbra combine`: ORs shard files of one bake into one file covering their shards.
/// @param inputs shard files, or directories whose shard files are all taken (within @p range)
/// @param range the shards to combine; the inputs' files outside it are left out, and those
///        inside must cover it exactly. Without it the files must cover one contiguous range.
/// @param outDir where the combined file goes (combinedFilePath)
/// @return the combined file's path.
/// @throw InputError (one line) as for mergeShardFiles, for files of different bakes, a gap in
/// the range, or an unwritable output.
std::string combineShardFiles(const std::vector<std::string>& inputs, std::optional<ShardRange> range,
                              const std::string& outDir);

}  // namespace penumbra
