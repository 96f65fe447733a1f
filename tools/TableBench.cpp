#include "TableBench.h"
#include "BenchSupport.h"
#include "TableBenchReport.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/CheckedMath.h"
#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"
#include "stream/util/Memory.h"
#include "stream/util/Npy.h"
#include "stream/util/Timer.h"

#include <fmt/format.h>
#include <tbb/info.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <sstream>
#include <tuple>

namespace penumbra {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

/// One row of the paper's table: a resolution, a sample count and a light-size factor.
struct RowSpec {
    std::string name;
    int width, height, samples;
    double lightScale;  ///< u and v are multiplied by this (2: four times the area)
};

const std::vector<RowSpec>& rowSpecs() {
    static const std::vector<RowSpec> rows = {
        {"640x480@256", 640, 480, 256, 1.0},     {"1280x960@256", 1280, 960, 256, 1.0},
        {"2560x1920@256", 2560, 1920, 256, 1.0}, {"1280x960@1024", 1280, 960, 1024, 1.0},
        {"1280x960@256-light4x", 1280, 960, 256, 2.0},
    };
    return rows;
}

/// Embree's time: device, scene and BVH build plus tracing.
double embreeSeconds(const json& s) { return s["embree"]["build_time_s"].get<double>() + s["embree"]["trace_time_s"].get<double>(); }

json oursColumns(const json& s) {
    const json& t = s["table2"];
    return {{"threads", s["threads"]},
            {"sort_s", t["sort_time_s"]},
            {"hierarchy_build_s", hpcBuildWallSeconds(s)},
            {"hierarchy_build_thread_s", t["hierarchy_build_time_s"]},
            {"penumbra_cast_s", t["penumbra_cast_time_s"]},
            {"time_s", hpcPaperSeconds(s)},
            {"samples_memory_bytes", t["samples_memory_bytes"]},
            {"hierarchy_memory_bytes", t["peak_hierarchy_memory_bytes"]},
            {"mask_memory_bytes", t["peak_mask_memory_bytes"]},
            {"scan_s", s["stream"]["scan_time_s"]},
            {"bake_total_s", t["total_time_s"]},
            {"peak_rss_bytes", s["child_peak_rss_bytes"]},
            {"process_wall_s", s["child_wall_s"]},
            {"process_cpu_s", s["child_cpu_s"]},
            {"triangles", s["counters"]["triangles_read"]},
            {"triangles_culled_at_root", s["counters"]["triangles_culled_at_root"]},
            {"hard_shadow_tests", s["counters"]["hard_shadow_tests"]}};
}

json embreeColumns(const json& s) {
    return {{"threads", s["threads"]},
            {"build_s", s["embree"]["build_time_s"]},
            {"trace_s", s["embree"]["trace_time_s"]},
            {"time_s", embreeSeconds(s)},
            {"rays", s["embree"]["rays"]},
            {"scene_bytes", s["embree"]["scene_bytes"]},
            {"scan_s", s["stream"]["scan_time_s"]},
            {"bake_total_s", s["table2"]["total_time_s"]},
            {"peak_rss_bytes", s["child_peak_rss_bytes"]},
            {"process_wall_s", s["child_wall_s"]},
            {"process_cpu_s", s["child_cpu_s"]}};
}

/// The scene of one row: the example with the row's resolution (times @p scale), samples and
/// light size, writing its output into @p work.
json rowScene(const json& scene, const RowSpec& row, double scale, const fs::path& work) {
    return resizedScene(scene, std::max(8, int(std::lround(row.width * scale))), std::max(6, int(std::lround(row.height * scale))),
                        row.samples, row.lightScale, work / "out.exr");
}

/// Runs both methods with --dump and counts the relations where they differ, classifying them
/// as ties of the blocking rule against the scene (penumbra compare --scene, in a child).
json mismatches(const fs::path& scene, int threads, const fs::path& work) {
    const fs::path ours = work / "dump-ours", theirs = work / "dump-embree";
    json a = bakeChild(scene, "hpc", threads, work, {"--dump", ours.string()});
    if (a.contains("error")) return a;
    json b = bakeChild(scene, "embree", threads, work, {"--dump", theirs.string(), "--disable", "sort"});
    if (b.contains("error")) return b;
    ChildResult c = compareDumps(ours, theirs, scene, work);
    std::error_code ec;
    fs::remove_all(ours, ec), fs::remove_all(theirs, ec);
    if (c.exitCode != 0 && c.exitCode != 3)
        return {{"error", fmt::format("compare exited with {}: {}", c.exitCode, lastLine(c.err))}};
    auto v = parseCompare(c.out);
    const uint64_t differing = v["only_a"] + v["only_b"];
    return {{"relations", v["relations"]},   {"blocked_ours", v["blocked_a"]}, {"blocked_embree", v["blocked_b"]},
            {"only_ours", v["only_a"]},      {"only_embree", v["only_b"]},     {"mismatches", differing},
            {"ties", v["ties"]},             {"non_ties", differing - v["ties"]},
            {"compare_s", c.wallSeconds}};
}


/// Points on a square floor, normals up, as an N x 6 .npy (for the root-cull scene).
void writeFloorPoints(const std::string& path, int side, float half) {
    std::vector<float> v;
    for (int i = 0; i < side; ++i)
        for (int j = 0; j < side; ++j) {
            const float x = -half + 2 * half * float(i) / float(side - 1), z = -half + 2 * half * float(j) / float(side - 1);
            v.insert(v.end(), {x, 0.0f, z, 0.0f, 1.0f, 0.0f});
        }
    const uint64_t shape[2] = {uint64_t(side) * side, 6};
    writeNpy(path, "<f4", shape, v.data(), v.size() * sizeof(float));
}

/// Root-cull throughput on one core. Receivers are points on the floor [-4, 4]^2 (y = 0), the
/// light a 2 x 2 square at height 5, so the reach box is [-4, 4] x [0, 5] x [-4, 4]. Grass
/// blades are added (a) far outside the reach box, where the reach test drops them before a
/// penumbra volume is built, and (b) inside the reach box, in a top corner beside the light:
/// their penumbra volumes lead away from the floor, so the root's V_L test culls them. The rate
/// is the added triangles over the added penumbra-cast time against a bake without them.
json cullThroughput(const BenchTableOptions& o, const fs::path& work) {
    writeFloorPoints((work / "floor.npy").string(), 100, 4.0f);
    const uint64_t blades = std::max<uint64_t>(1, o.cullTriangles / 5);  // grass: 5 triangles a blade
    auto scene = [&](const json& grass) {
        return json{{"geometry", {grass}},
                    {"lights", {{{"type", "rect"}, {"center", {0, 5, 0}}, {"u", {2, 0, 0}}, {"v", {0, 0, 2}}, {"samples", 256}}}},
                    {"receivers", {{"type", "points"}, {"path", (work / "floor.npy").string()}}},
                    {"output", (work / "cull-out.npy").string()},
                    // The caster's own cull is measured: the bucket pass must hand it every blade.
                    {"bake", {{"cull_before_spill", false}}}};
    };
    const json grassBase = {{"type", "grass"}, {"height", {0.15, 0.3}}, {"bend", {0.0, 0.1}}, {"seed", 7}};
    json base = grassBase, far = grassBase, beside = grassBase;
    base["count"] = 1, base["area"] = {{-0.1, -0.1}, {0.1, 0.1}}, base["transform"] = {{"translate", {500, 0, 500}}};
    far["count"] = blades, far["area"] = {{40, 40}, {140, 140}};
    beside["count"] = blades, beside["area"] = {{3.0, 3.0}, {3.9, 3.9}}, beside["transform"] = {{"translate", {0, 4.55, 0}}};

    json out = {{"triangles_requested", o.cullTriangles}, {"threads", 1}, {"cases", json::array()}};
    // The cull's own cost: the cast pass without reading the replay, which on one thread is
    // serial with it (the stream's rate is the separate "stream + bucket pass" column).
    auto cullSeconds = [](const json& s) {
        return s["table2"]["penumbra_cast_time_s"].get<double>() - s["table2"].value("replay_read_time_s", 0.0);
    };
    auto run = [&](const std::string& name, const json& grass) {
        const fs::path file = work / ("cull-" + name + ".json");
        writeText(file.string(), scene(grass).dump(2));
        return bestOf(o.repeat, cullSeconds, [&] { return bakeChild(file, "hpc", 1, work); });
    };
    json b = run("base", base);
    if (b.contains("error")) return {{"error", b["error"]}};
    const std::vector<std::tuple<std::string, std::string, json>> cases = {{"outside reach", "far", far},
                                                                           {"beside the light", "beside", beside}};
    for (const auto& [name, file, grass] : cases) {
        json s = run(file, grass);
        if (s.contains("error")) {
            out["cases"].push_back({{"case", name}, {"error", s["error"]}});
            continue;
        }
        const double added = s["counters"]["triangles_read"].get<double>() - b["counters"]["triangles_read"].get<double>();
        const double culled = s["counters"]["triangles_culled_at_root"].get<double>() -
                              b["counters"]["triangles_culled_at_root"].get<double>();
        const double seconds = cullSeconds(s) - cullSeconds(b);
        out["cases"].push_back({{"case", name},
                                {"triangles", added},
                                {"culled_at_root", culled},
                                {"cast_s", seconds},
                                {"triangles_per_second_per_core", seconds > 0 ? culled / seconds : 0.0},
                                {"sort_pass_triangles_per_second", added / std::max(1e-9, s["table2"]["sort_time_s"].get<double>())},
                                {"peak_rss_bytes", s["child_peak_rss_bytes"]}});
    }
    return out;
}

}  // namespace

std::vector<std::string> tableRowNames() {
    std::vector<std::string> names;
    for (const RowSpec& r : rowSpecs()) names.push_back(r.name);
    return names;
}

CLI::App* addBenchTableCommand(CLI::App& bench, BenchTableOptions& o) {
    CLI::App* cmd = bench.add_subcommand("table2", "the paper's Table 2: ours against Embree on the procedural scenes");
    cmd->add_option("--scenes", o.scenes, "scene names in --examples or .json paths (default grids,flowers,sponza-like)")
        ->delimiter(',');
    cmd->add_option("--rows", o.rows, "rows to run (default all): " + fmt::format("{}", fmt::join(tableRowNames(), ",")))
        ->delimiter(',');
    cmd->add_option("--scale", o.scale, "resolution factor for a quick run, e.g. 0.25 (default 1: the paper's sizes)");
    cmd->add_option("--threads", o.threads, "thread count, or a list such as 1,2 to measure scaling (default: all cores)")
        ->delimiter(',');
    cmd->add_option("--json", o.jsonPath, "write the full result as JSON (rewritten after every row)");
    cmd->add_option("--markdown", o.markdownPath, "regenerate the Table 2 section of this BENCHMARKS.md");
    cmd->add_option("--examples", o.examplesDir, "directory of the scene files (default ./examples)");
    cmd->add_option("--tmp", o.tmpDir, "directory for scenes, dumps and bucket files (default: the system temp dir)");
    cmd->add_option("--repeat", o.repeat, "timed runs per row and method; the fastest is reported (default 1)");
    cmd->add_flag("--no-embree", o.noEmbree, "measure ours only");
    cmd->add_flag("--no-compare", o.noCompare, "skip the --dump runs that count mismatches against Embree");
    cmd->add_flag("--no-cull", o.noCull, "skip the root-cull throughput measurement");
    cmd->add_option("--cull-triangles", o.cullTriangles, "triangles per root-cull case (default 20M)")
        ->check(CLI::Range(uint64_t(1), kMaxSceneTriangles));
    cmd->add_flag("-q,--quiet", o.quiet, "no progress lines on stderr");
    return cmd;
}

namespace {

/// The rows --rows names (all when it is empty), once every option is checked.
/// @throw InputError naming the option with a bad value.
std::vector<RowSpec> checkedRows(const BenchTableOptions& o) {
    if (!(o.scale > 0.0 && o.scale <= 4.0)) throw InputError(fmt::format("--scale: must be in (0, 4], got {}", o.scale));
    if (o.repeat < 1 || o.repeat > 100) throw InputError(fmt::format("--repeat: must be in 1..100, got {}", o.repeat));
    for (int t : o.threads)
        if (t < 1 || t > 1024) throw InputError(fmt::format("--threads: each count must be in 1..1024, got {}", t));
    if (o.cullTriangles == 0) throw InputError("--cull-triangles: must be positive");
    const std::vector<std::string> known = tableRowNames();
    for (const std::string& name : o.rows)
        if (std::find(known.begin(), known.end(), name) == known.end())
            throw InputError(fmt::format("--rows: unknown row \"{}\" (known: {})", name, fmt::join(known, ", ")));
    std::vector<RowSpec> rows;
    for (const RowSpec& r : rowSpecs())
        if (o.rows.empty() || std::find(o.rows.begin(), o.rows.end(), r.name) != o.rows.end()) rows.push_back(r);
    return rows;
}

/// One run of the table: its options, thread counts, scratch folder and the result so far.
struct TableRun {
    const BenchTableOptions& o;
    std::vector<int> threadList;  ///< ours runs at each; the last is the table's
    int tableThreads;
    fs::path tmp;
    json result;
    Stopwatch watch;

    void save() const {
        if (!o.jsonPath.empty()) writeText(o.jsonPath, result.dump(2) + "\n");
    }
    void progress(const std::string& line) const {
        if (!o.quiet) fmt::print(stderr, "[table2] {}\n", line);
    }
};

/// Ours at every thread count, fastest of `repeat` each: the last count's run, and the scaling
/// entry (times per count and the speed-ups) in @p scaling.
json oursAtEveryThreadCount(const TableRun& run, const fs::path& file, const fs::path& work, json& scaling) {
    json ours;
    scaling["threads"] = scaling["seconds"] = scaling["cast_seconds"] = json::array();
    for (int threads : run.threadList) {
        ours = bestOf(run.o.repeat, hpcPaperSeconds, [&] { return bakeChild(file, "hpc", threads, work); });
        scaling["threads"].push_back(threads > 0 ? threads : int(tbb::info::default_concurrency()));
        scaling["seconds"].push_back(ours.contains("error") ? json() : json(hpcPaperSeconds(ours)));
        scaling["cast_seconds"].push_back(ours.contains("error") ? json() : ours["table2"]["penumbra_cast_time_s"]);
    }
    const json& s = scaling["seconds"];
    const json& c = scaling["cast_seconds"];
    if (run.threadList.size() > 1 && !s.front().is_null() && !s.back().is_null()) {
        scaling["speedup"] = s.front().get<double>() / s.back().get<double>();
        scaling["cast_speedup"] = c.front().get<double>() / c.back().get<double>();
    }
    return ours;
}

/// Embree on the same scene, and the mismatches against ours, into @p row; @return the
/// progress line's part.
std::string embreeColumnsOf(const TableRun& run, const fs::path& file, const fs::path& work, double ours, json& row) {
    // Embree does not need our sorted buckets: it reads the stream directly.
    json e = bestOf(run.o.repeat, embreeSeconds,
                    [&] { return bakeChild(file, "embree", run.tableThreads, work, {"--disable", "sort"}); });
    std::string line;
    if (e.contains("error")) {
        row["embree"] = {{"error", e["error"]}};
    } else {
        row["embree"] = embreeColumns(e);
        row["ratio"] = embreeSeconds(e) / ours;
        line += fmt::format("; Embree {:.2f} s, peak {} MiB; Embree/ours {:.2f}", embreeSeconds(e),
                            formatMiB(row["embree"]["peak_rss_bytes"]), row["ratio"].get<double>());
    }
    if (!run.o.noCompare) {
        row["mismatches"] = mismatches(file, run.tableThreads, work);
        if (!row["mismatches"].contains("error"))
            line += fmt::format("; mismatches {} ({} ties)", row["mismatches"]["mismatches"].get<uint64_t>(),
                                row["mismatches"]["ties"].get<uint64_t>());
    }
    return line;
}

/// One row of the table for scene @p name (its JSON @p base), appended to the result.
void runTableRow(TableRun& run, const std::string& name, const json& base, const RowSpec& spec) {
    const fs::path work = run.tmp / (name + "-" + spec.name);
    fs::create_directories(work);
    const json scene = rowScene(base, spec, run.o.scale, work);
    const fs::path file = work / "scene.json";
    writeText(file.string(), scene.dump(2));
    json row = {{"scene", name},
                {"row", spec.name},
                {"width", scene["receivers"]["width"]},
                {"height", scene["receivers"]["height"]},
                {"nominal_width", spec.width},
                {"samples", spec.samples},
                {"light_scale", spec.lightScale * spec.lightScale}};
    run.progress(fmt::format("{} {} ({}×{}): running", name, spec.name, row["width"].get<int>(), row["height"].get<int>()));
    json scaling = {{"scene", name}, {"row", spec.name}};
    const json ours = oursAtEveryThreadCount(run, file, work, scaling);
    if (ours.contains("error")) {
        row["error"] = ours["error"];
        run.result["rows"].push_back(row);
        run.save();
        run.progress(fmt::format("{} {}: {}", name, spec.name, row["error"].get<std::string>()));
        return;
    }
    row["receivers"] = ours["receivers"];
    row["light_samples"] = ours["light_samples"];
    row["ours"] = oursColumns(ours);
    if (run.threadList.size() > 1) run.result["thread_scaling"].push_back(scaling);
    std::string line = fmt::format("{} {}: ours {:.2f} s, peak {} MiB", name, spec.name, hpcPaperSeconds(ours),
                                   formatMiB(row["ours"]["peak_rss_bytes"]));
    if (!run.o.noEmbree) line += embreeColumnsOf(run, file, work, hpcPaperSeconds(ours), row);
    std::error_code ec;
    fs::remove_all(work, ec);
    run.result["rows"].push_back(row);
    run.result["elapsed_s"] = run.watch.seconds();
    run.save();
    run.progress(line + fmt::format(" [{:.0f} s elapsed]", run.watch.seconds()));
}

/// The root-cull throughput cases, into the result.
void runRootCull(TableRun& run) {
    run.progress(fmt::format("root cull: {} triangles per case", run.o.cullTriangles));
    const fs::path work = run.tmp / "cull";
    fs::create_directories(work);
    run.result["root_cull"] = cullThroughput(run.o, work);
    for (const json& c : run.result["root_cull"].value("cases", json::array()))
        if (c.contains("triangles_per_second_per_core"))
            run.progress(fmt::format("root cull, {}: {:.1f}M triangles/s/core", c["case"].get<std::string>(),
                                     c["triangles_per_second_per_core"].get<double>() / 1e6));
}

}  // namespace

void runBenchTable(const BenchTableOptions& o, const std::string& commandLine) {
    checkDistinctFiles({{"--json", o.jsonPath}, {"--markdown", o.markdownPath}});
    checkMarkdownFile(o.markdownPath);
    const std::vector<RowSpec> rows = checkedRows(o);
    std::vector<std::pair<std::string, json>> scenes;
    for (const std::string& name : o.scenes) scenes.emplace_back(sceneName(name), benchCameraScene(o.examplesDir, name));

    const std::vector<int> threadList = o.threads.empty() ? std::vector<int>{0} : o.threads;
    const int tableThreads = threadList.back() > 0 ? threadList.back() : int(tbb::info::default_concurrency());
    TempDir tmp(o.tmpDir);
    TableRun run{o, threadList, tableThreads, tmp.path, json::object(), Stopwatch()};
    run.result = {{"command", commandLine},
                  {"date", utcNow()},
                  {"machine", machineInfo()},
                  {"scale", o.scale},
                  {"repeat", o.repeat},
                  {"threads_table", tableThreads},
                  {"threads", threadList},
                  {"load_average_start", loadAverage()},
                  {"rows", json::array()}};
    for (const auto& [name, base] : scenes)
        for (const RowSpec& spec : rows) runTableRow(run, name, base, spec);
    if (!o.noCull) runRootCull(run);
    run.result["elapsed_s"] = run.watch.seconds();
    run.result["load_average_end"] = loadAverage();
    run.result["bench_process_peak_rss_bytes"] = peakRssBytes();
    run.save();
    const std::string md = table2Markdown(run.result);
    // Read only now: the file may have been edited during a run that takes half an hour.
    if (!o.markdownPath.empty())
        writeText(o.markdownPath, replaceTable2Section(fs::exists(o.markdownPath) ? slurpFile(o.markdownPath) : "", md));
    fmt::print("{}", md);
}

}  // namespace penumbra
