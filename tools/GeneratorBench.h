#pragma once
/// @file GeneratorBench.h
/// @brief Generator throughput: triangles per second that each procedural generator delivers
/// through TriangleSource::read() in kTriangleChunk chunks, per thread count. Used by
/// `penumbra bench generators` and meant to be callable from a wider `penumbra bench`.

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace penumbra {

/// @brief Times every generator in a fixed set of representative configurations.
///
/// For each configuration and thread count (set with tbb::global_control) the source is opened
/// (setup time reported separately: trees, terrain height caches), one chunk is read to warm up,
/// then @p trianglesPerGenerator triangles are pulled through read() in kTriangleChunk chunks and
/// discarded, rewinding whenever a small generator runs out.
/// @return {"triangles_per_generator", "chunk", "generators": [{"name", "entry", "triangles_per_item",
///         "results": [{"threads", "seconds", "cpu_seconds", "setup_seconds", "triangles_per_second",
///         "triangles_per_cpu_second"}]}]}. CPU time is the whole process's, over all threads.
/// @param only when not empty, measure only the configurations whose name contains it
/// @param repeat runs per configuration and thread count; the fastest is reported
nlohmann::json benchGenerators(uint64_t trianglesPerGenerator, std::vector<int> threadCounts, const std::string& only = "",
                               int repeat = 1);

/// @brief The result of benchGenerators() as a Markdown table: million triangles per wall-clock
/// second and per CPU second, for each thread count.
std::string generatorBenchTable(const nlohmann::json& result);

struct BenchGeneratorsOptions {
    uint64_t triangles = 20000000;
    std::vector<int> threads{1, 2};
    std::string jsonPath;  ///< also write the JSON result here when not empty
    std::string only;      ///< substring filter on configuration names
    int repeat = 1;        ///< runs per measurement, best reported
};

/// @brief Adds `bench generators` under @p bench (the `bench` subcommand). @return the new subcommand.
CLI::App* addBenchGeneratorsCommand(CLI::App& bench, BenchGeneratorsOptions& options);

/// @brief Runs the benchmark, prints the table to stdout, and writes the JSON if asked.
/// @throw InputError for bad options or an unwritable JSON path.
void runBenchGenerators(const BenchGeneratorsOptions& options);

}  // namespace penumbra
