#pragma once
/// @file BakeCommand.h
/// @brief `penumbra bake SCENE.json [options]`: the command line of a bake, turned into the
/// scene's overrides and BakeSettings (bake/Pipeline.h). `penumbra merge` is this command with
/// `--merge` (ShardCommands.h).

#include "ShardCommands.h"

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace penumbra {

/// The bake command's options as parsed; the Option pointers tell given from default.
struct BakeCommand {
    std::string scenePath, output, method = "hpc", statsPath, dumpDir, visibilityPath;
    int threads = 0;
    bool quiet = false, keepBuckets = false;
    std::vector<std::string> disabled;
    std::string simd, sampleTable, closedCasters, embreeFilter, memoryBudget, tmpDir;
    int mapResolution = 0;
    double mapBias = -1;
    std::string mapLookup;  ///< empty: the scene's
    int mapTaps = 0;        ///< 0: the scene's
    ShardCli shard;
    CLI::Option *outputOption = nullptr, *statsOption = nullptr, *dumpOption = nullptr, *tmpOption = nullptr,
                *budgetOption = nullptr, *mapResolutionOption = nullptr, *mapBiasOption = nullptr, *mapTapsOption = nullptr;
};

/// @brief Adds the `bake` subcommand to @p app, parsing into @p command (which must outlive the
/// parse). @return the subcommand, to test whether it was chosen.
CLI::App* addBakeCommand(CLI::App& app, BakeCommand& command);

/// @brief Runs the bake and prints its summary line (unless --quiet).
/// @throw InputError for bad options, a bad scene or a failed bake (no partial output remains).
void runBakeCommand(const BakeCommand& command);

/// @brief A --memory-budget as typed ("256M", "2G"), in bytes (bake, merge, slurm).
/// @throw InputError for text parseByteSize() refuses, or 0.
uint64_t parseMemoryBudget(const std::string& text);

}  // namespace penumbra
