#pragma once
/// @file TableBench.h
/// @brief `penumbra bench table2`: the paper's Table 2 (Laine & Aila 2005) on the procedural
/// scenes, our bake against `--method embree` over the identical receivers and light samples,
/// plus thread scaling and root-cull throughput. Every measured bake runs in a child process
/// (`penumbra bake ... --stats`), so each method's peak RSS is its own. docs/BENCHMARKS.md,
/// section "Table 2", says what every column means.

#include "TableBenchReport.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace penumbra {

struct BenchTableOptions {
    std::vector<std::string> scenes{"grids", "flowers", "sponza-like"};  ///< names in examplesDir, or .json paths
    std::vector<std::string> rows;  ///< row names (tableRowNames()); empty: all
    double scale = 1.0;             ///< resolution factor for quick runs (1: the paper's sizes)
    std::vector<int> threads;       ///< ours at each count (scaling); the last is the table's. Empty: all cores
    std::string jsonPath, markdownPath;
    std::string examplesDir = "examples";
    std::string tmpDir;             ///< where scenes, outputs and dumps go (default: system temp dir)
    int repeat = 1;                 ///< timed runs per row and method; the fastest is reported
    bool noEmbree = false;
    bool noCompare = false;         ///< skip the --dump runs and the mismatch count
    bool noCull = false;            ///< skip the root-cull throughput measurement
    uint64_t cullTriangles = 20'000'000;
    bool quiet = false;
};

/// @brief Row names in table order: "640x480@256", "1280x960@256", "2560x1920@256",
/// "1280x960@1024", "1280x960@256-light4x".
std::vector<std::string> tableRowNames();

/// @brief Adds `bench table2` under @p bench. @return the new subcommand.
CLI::App* addBenchTableCommand(CLI::App& bench, BenchTableOptions& options);

/// @brief Runs the benchmark; writes the JSON (after every row, so an interrupted run keeps what
/// it measured) and the Markdown when asked, and prints the Markdown to stdout.
/// @param commandLine the invocation, recorded in the outputs.
/// @throw InputError for bad options, missing scenes or unwritable outputs. A failing bake does
/// not stop the run: its row records the error.
void runBenchTable(const BenchTableOptions& options, const std::string& commandLine);

}  // namespace penumbra
