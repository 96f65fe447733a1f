#pragma once
/// @file Pipeline.h
/// @brief A whole bake: stream the scene, make receivers and light samples, sort blockers, cast
/// with the chosen method, and write the outputs, dump and stats.

#include "bake/BakeCapture.h"
#include "bake/Scene.h"
#include "bake/shard/ShardSettings.h"

#include <nlohmann/json.hpp>

#include <string>

namespace penumbra {

/// Most worker threads a bake or `generate` accepts (`--threads`); more is a typing mistake, and
/// four sub-tiles per thread must stay countable.
inline constexpr int kMaxThreads = 4096;

/// @brief How to run a bake (the CLI's flags); the scene says what to bake.
struct BakeSettings {
    std::string method = "hpc";  ///< a registered method (bake/cast/Caster.h: casterNames())
    int threads = 0;          ///< 0: all cores; at most kMaxThreads
    /// The threads first asked for, when runBake() tries again on fewer (ThreadsDoNotFit); 0: threads.
    int threadsWanted = 0;
    std::string statsPath;    ///< JSON stats, optional
    std::string dumpDir;      ///< receivers.npy, samples.npy, masks.npy, optional
    std::string visibilityPath;  ///< --visibility: every receiver's visible fraction as float32 .npy, optional
    bool quiet = false;
    uint64_t memoryBudget = 0;  ///< --memory-budget in bytes; 0: unlimited
    std::string tmpDir;         ///< where bucket files go (default: the system temp dir)
    bool keepBuckets = false;   ///< leave bucket files behind for debugging
    ShardSettings shard;        ///< --shard, penumbra merge, --checkpoint (bake/shard)
    /// A library caller's results (BakeCapture.h): when set, the bake moves its receivers, results
    /// and receiver kind here, and writes the scene's outputs only when capture->writeOutputs.
    BakeCapture* capture = nullptr;
};

/// @brief Runs the bake and writes the scene's output (EXR + PNG preview for camera receivers,
/// .npy visibilities for points).
/// @return the stats document (also written to settings.statsPath when set).
/// @throw InputError for every user-facing problem; no partial output file is left behind.
/// Cancellable: ProgressReporter::update() throws Cancelled after requestCancel() (Progress.h).
nlohmann::json runBake(const SceneDesc& scene, const BakeSettings& settings);

/// @brief Writes the outputs the CLI writes for a captured bake (EXR + PNG, .npy, lightmap, ...),
/// byte for byte, to @p output, all together or none (OutputSet).
/// @throw InputError naming the file that cannot be written.
void writeCapturedOutputs(const SceneDesc& scene, const BakeCapture& capture, const std::string& output);

}  // namespace penumbra
