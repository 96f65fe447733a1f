#pragma once
/// @file MethodsBench.h
/// @brief `penumbra bench methods`: every method on the Table 2 scenes, each bake in its own child
/// process (tools/BenchSupport.h), against hpc: time and peak RSS; for the exact methods
/// (reference where feasible, embree, ssv) the relations they decide differently from hpc, with
/// ties of the blocking rule classified (`penumbra compare --scene`); for the approximate ones
/// (penumbra-map, hh) the error of the visible fraction per receiver. hh runs on the lightmap
/// example at several sample counts. docs/BENCHMARKS.md, section "Methods", explains the columns.

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace penumbra {

struct BenchMethodsOptions {
    std::vector<std::string> scenes{"grids", "flowers", "sponza-like"};
    std::vector<std::string> sizes{"640x480", "1280x960"};
    std::vector<std::string> methods{"embree", "ssv", "penumbra-map", "reference", "hh"};  ///< besides hpc
    std::string lightmap = "lightmap";       ///< the scene hh runs on
    std::vector<int> hhSamples{64, 256, 1024};
    double scale = 1.0;
    int threads = 0;                         ///< 0: all cores
    int repeat = 1;
    double referenceLimit = 2e10;            ///< relation-triangle tests beyond which the reference is skipped
    std::string jsonPath, markdownPath;
    std::string renderPath;                  ///< --render: only the Markdown of this earlier JSON result
    std::string examplesDir = "examples";
    std::string tmpDir;
    bool noCompare = false;                  ///< skip the --dump runs and the mismatch counts
    bool quiet = false;
};

/// @brief Adds `bench methods` under @p bench.
CLI::App* addBenchMethodsCommand(CLI::App& bench, BenchMethodsOptions& options);

/// @brief Runs the benchmark, writes the JSON (after every row) and the Markdown section when
/// asked, and prints the Markdown. @throw InputError for bad options or missing scenes; a failing
/// bake is recorded in its row and does not stop the run.
void runBenchMethods(const BenchMethodsOptions& options, const std::string& commandLine);

/// @brief Prints the Markdown of @p result and, unless @p markdownPath is empty, splices it into
/// that file's generated "Methods" section.
void writeMethodsMarkdown(const nlohmann::json& result, const std::string& markdownPath);

/// @brief The generated Markdown for a result document.
std::string methodsMarkdown(const nlohmann::json& result);

/// @brief Replaces the generated "Methods" section of a BENCHMARKS.md text (or appends it).
std::string replaceMethodsSection(const std::string& document, const std::string& generated);

}  // namespace penumbra
