#pragma once
/// @file BakeStats.h
/// @brief The stats JSON of a bake (`--stats`): the paper's Table 2 columns, counters, the memory
/// plan, the stream and bucket passes. Each stage fills its part of BakeStatsInputs; bakeStats()
/// lays them out (the keys are documented in README.md and docs/BENCHMARKS.md).

#include "bake/MemoryPlan.h"
#include "bake/cast/CastOptions.h"
#include "bake/cast/ClosedSolids.h"
#include "bake/light/Light.h"
#include "bucket/BucketFiles.h"
#include "bucket/BucketPlan.h"
#include "receivers/ReceiverSet.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace penumbra {

struct SceneDesc;
struct ReceiverResults;

struct BakeStatsInputs {
    const SceneDesc& scene;
    const std::string& method;
    int threads;
    const ReceiverSet& receivers;
    const LightSamples& samples;
    const CastOptions& options;  ///< with the epsilon length
    const ReceiverResults& results;
    CastStats cast;
    const BucketStats& buckets;
    const MemoryPlan& plan;
    const MemoryDemand& demand;
    uint64_t triangles = 0;
    const BucketReplaySource* replay = nullptr;  ///< the bucket replay, for its read counters
    const OpenedSolids* openedSolids = nullptr;
    /// A by-receivers shard's receivers: blocked_relations counts theirs only (the others are not
    /// cast, and their results read as fully blocked). Null: every receiver.
    const std::vector<uint32_t>* castShare = nullptr;
    double streamSeconds = 0, castSeconds = 0, refineSeconds = 0, totalSeconds = 0;
    /// Opening the sources before the scan: an OBJ's check pass, a glTF's JSON (minutes for a large OBJ).
    double openSeconds = 0;
};

/// @brief The stats document of a bake.
nlohmann::json bakeStats(const BakeStatsInputs& in);

/// @brief Writes @p stats to @p path (pretty-printed, atomically).
/// @throw InputError naming the path when it cannot be written.
void writeStats(const std::string& path, const nlohmann::json& stats);

}  // namespace penumbra
