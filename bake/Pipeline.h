#pragma once
/// @file Pipeline.h
/// @brief A whole bake: stream the scene, make receivers and light samples, sort blockers, cast
/// with the chosen method, and write the outputs, dump and stats.

#include "bake/Scene.h"

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
    std::string statsPath;    ///< JSON stats, optional
    std::string dumpDir;      ///< receivers.npy, samples.npy, masks.npy, optional
    bool quiet = false;
    uint64_t memoryBudget = 0;  ///< --memory-budget in bytes; 0: unlimited
    std::string tmpDir;         ///< where bucket files go (default: the system temp dir)
    bool keepBuckets = false;   ///< leave bucket files behind for debugging
};

/// @brief Runs the bake and writes the scene's output (EXR + PNG preview for camera receivers,
/// .npy visibilities for points).
/// @return the stats document (also written to settings.statsPath when set).
/// @throw InputError for every user-facing problem; no partial output file is left behind.
nlohmann::json runBake(const SceneDesc& scene, const BakeSettings& settings);

}  // namespace penumbra
