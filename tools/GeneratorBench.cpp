#include "GeneratorBench.h"

#include "bake/TbbControl.h"
#include "procedural/Generators.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/CheckedMath.h"
#include "stream/util/Error.h"
#include "stream/util/Timer.h"
#include "stream/SourceRegistry.h"

#include <fmt/format.h>

#include <tbb/global_control.h>

#include <chrono>
#include <ctime>
#include <span>

namespace penumbra {
namespace {


/// Representative configurations: the ones the example scenes use, at streaming sizes.
std::vector<std::pair<std::string, nlohmann::json>> benchCases() {
    using nlohmann::json;
    const json terrain = {{"area", {{-500, -500}, {500, 500}}}, {"resolution", 512}, {"amplitude", 6}, {"octaves", 6},
                          {"frequency", 0.004}, {"seed", 3}};
    return {
        {"grid", {{"type", "grid"}, {"cells", 44}, {"levels", 3}}},
        {"terrain", {{"type", "terrain"}, {"area", {{-500, -500}, {500, 500}}}, {"resolution", 1024}, {"octaves", 6}}},
        {"grass", {{"type", "grass"}, {"count", 1000000000}, {"area", {{-100, -100}, {100, 100}}}}},
        {"grass (terrain, clumps)",
         {{"type", "grass"}, {"count", 1000000000}, {"terrain", terrain}, {"clump", {{"frequency", 0.05}, {"threshold", -0.1}}}}},
        {"flowers", {{"type", "flowers"}, {"count", 100000000}, {"area", {{-100, -100}, {100, 100}}}}},
        {"tree", {{"type", "tree"}, {"depth", 5}, {"leaves_per_branch", 10}}},
        {"forest", {{"type", "forest"}, {"count", 100000}, {"terrain", terrain}}},
        {"scatter (tree instances)",
         {{"type", "scatter"}, {"count", 1000000}, {"area", {{-100, -100}, {100, 100}}}, {"source", {{"type", "tree"}}}}},
        {"colonnade", {{"type", "colonnade"}}},
    };
}

/// One timed pull of @p triangles from a freshly opened source, on at most @p threads threads.
nlohmann::json measureOnce(const std::string& name, const nlohmann::json& entry, uint64_t triangles, int threads,
                           std::vector<Triangle>& chunk) {
    nlohmann::json params = entry;
    const std::string type = params["type"];
    params.erase("type");
    // Kept under an address-space limit: lifting it would start workers there, and TBB's throw
    // from the destructor aborted the bench (64-70 MiB).
    const ScopedTbbControl limit(tbb::global_control::max_allowed_parallelism, size_t(std::max(threads, 1)));
    const Stopwatch setupWatch;
    TriangleSourcePtr source = openSource(type, SourceRequest{params, "bench", name, "."});
    source->read(chunk);  // warm-up: first-touch of the chunk, TBB workers started
    const double setup = setupWatch.seconds();
    float sink = 0;  // something read from every chunk, so nothing can be skipped
    uint64_t pulled = 0;
    const Stopwatch watch;
    const std::clock_t cpuStart = std::clock();  // all threads of the process
    while (pulled < triangles) {
        const size_t want = size_t(std::min<uint64_t>(chunk.size(), triangles - pulled));
        size_t n = source->read(std::span<Triangle>(chunk.data(), want));
        if (n == 0) {
            source->rewind();
            continue;
        }
        sink += chunk[n - 1].v[2].y;
        pulled += n;
    }
    const double seconds = watch.seconds();
    const double cpuSeconds = double(std::clock() - cpuStart) / CLOCKS_PER_SEC;
    return {{"threads", threads},
            {"seconds", seconds},
            {"cpu_seconds", cpuSeconds},
            {"triangles_per_cpu_second", cpuSeconds > 0 ? double(pulled) / cpuSeconds : 0.0},
            {"setup_seconds", setup},
            {"triangles_per_second", seconds > 0 ? double(pulled) / seconds : 0.0},
            {"checksum", sink}};
}

}  // namespace

nlohmann::json benchGenerators(uint64_t trianglesPerGenerator, std::vector<int> threadCounts, const std::string& only,
                               int repeat) {
    registerProceduralGenerators();
    nlohmann::json out = {{"triangles_per_generator", trianglesPerGenerator}, {"chunk", kTriangleChunk}, {"repeat", repeat}};
    std::vector<Triangle> chunk(kTriangleChunk);
    for (auto& [name, entry] : benchCases()) {
        if (!only.empty() && name.find(only) == std::string::npos) continue;
        nlohmann::json row = {{"name", name}, {"entry", entry}, {"results", nlohmann::json::array()}};
        for (int threads : threadCounts) {
            // Best of `repeat`: on a shared machine the fastest run is the one least disturbed.
            nlohmann::json best;
            for (int r = 0; r < std::max(repeat, 1); ++r) {
                nlohmann::json run = measureOnce(name, entry, trianglesPerGenerator, threads, chunk);
                if (best.is_null() || run["triangles_per_second"].get<double>() > best["triangles_per_second"].get<double>())
                    best = run;
            }
            row["results"].push_back(best);
        }
        out["generators"].push_back(row);
    }
    return out;
}

std::string generatorBenchTable(const nlohmann::json& result) {
    // Wall-clock rate per thread count, and the rate per CPU second: on a shared machine the
    // second shows what the code does when it gets the cores it asked for.
    std::string header = "| generator |", rule = "|---|";
    for (const auto& r : result["generators"][0]["results"]) {
        const int t = r["threads"].get<int>();
        header += fmt::format(" {} thread{} Mtri/s | per CPU-s |", t, t == 1 ? "" : "s");
        rule += "---:|---:|";
    }
    std::string table = header + "\n" + rule + "\n";
    for (const auto& g : result["generators"]) {
        table += "| " + g["name"].get<std::string>() + " |";
        for (const auto& r : g["results"])
            table += fmt::format(" {:.1f} | {:.1f} |", r["triangles_per_second"].get<double>() / 1e6,
                                 r["triangles_per_cpu_second"].get<double>() / 1e6);
        table += "\n";
    }
    return table;
}

CLI::App* addBenchGeneratorsCommand(CLI::App& bench, BenchGeneratorsOptions& options) {
    CLI::App* cmd = bench.add_subcommand("generators", "triangles per second of every procedural generator");
    cmd->add_option("--triangles", options.triangles, "triangles pulled per generator and thread count (default 20M)")
        ->check(CLI::Range(uint64_t(1), kMaxSceneTriangles));
    cmd->add_option("--threads", options.threads, "thread counts to measure, e.g. 1,2 (default)")->delimiter(',');
    cmd->add_option("--json", options.jsonPath, "also write the full result as JSON");
    cmd->add_option("--only", options.only, "measure only generators whose name contains this text");
    cmd->add_option("--repeat", options.repeat, "runs per measurement; the fastest is reported (default 1)");
    return cmd;
}

void runBenchGenerators(const BenchGeneratorsOptions& options) {
    if (options.triangles == 0) throw InputError("--triangles: must be positive");
    for (int t : options.threads)
        if (t < 1 || t > 1024) throw InputError(fmt::format("--threads: each count must be in 1..1024, got {}", t));
    if (options.threads.empty()) throw InputError("--threads: give at least one thread count");
    if (options.repeat < 1 || options.repeat > 100) throw InputError(fmt::format("--repeat: must be in 1..100, got {}", options.repeat));
    if (!options.jsonPath.empty()) checkOutputPath(options.jsonPath);  // before minutes of measuring, as bench table2
    nlohmann::json result = benchGenerators(options.triangles, options.threads, options.only, options.repeat);
    if (result["generators"].empty()) throw InputError("--only: no generator matches \"" + options.only + "\"");
    fmt::print("{}", generatorBenchTable(result));
    if (!options.jsonPath.empty()) {
        std::string text = result.dump(2) + "\n";
        ensureParentDirectory(options.jsonPath);
        writeFileAtomically(options.jsonPath, std::span(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
    }
}

}  // namespace penumbra
