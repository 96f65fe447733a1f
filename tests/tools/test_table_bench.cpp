// `penumbra bench table2` end to end at a tiny scale: every column of the JSON is there with
// plausible values, the ratio is Embree's time over ours, mismatches are all ties, and
// --markdown regenerates only its own section of a BENCHMARKS.md.

#include "CliRunner.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

using namespace penumbra::test;

namespace {

const std::string kBegin = "<!-- penumbra bench table2: begin";

}  // namespace

TEST_CASE("bench table2 at a tiny scale: columns, ratio, ties and the Markdown section", "[cli][bench]") {
    ScratchDir dir("table2");
    const std::string original = slurp(std::string(PENUMBRA_SOURCE_DIR) + "/docs/BENCHMARKS.md");
    REQUIRE(original.find("## Generators") != std::string::npos);
    std::ofstream(dir / "BENCHMARKS.md") << original;
    const std::string common = "bench table2 -q --scale 0.05 --rows 640x480@256 --scenes grids --examples " +
                               std::string(PENUMBRA_SOURCE_DIR) + "/examples --tmp " + dir.path.string() +
                               " --markdown " + (dir / "BENCHMARKS.md");

    RunResult r = runPenumbra(common + " --threads 1,2 --cull-triangles 50000 --json " + (dir / "t2.json"));
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    const nlohmann::json j = nlohmann::json::parse(slurp(dir / "t2.json"));

    CHECK_THAT(j["command"].get<std::string>(), Catch::Contains("bench table2") && Catch::Contains("--scale 0.05"));
    for (const char* key : {"cpu", "cores", "ram_bytes", "os", "compiler", "commit"}) CHECK(j["machine"].contains(key));
    CHECK(j["machine"]["cores"].get<int>() >= 1);
    CHECK(j.contains("load_average_start"));
    REQUIRE(j["rows"].size() == 1);
    const nlohmann::json& row = j["rows"][0];
    INFO(row.dump(2));
    REQUIRE_FALSE(row.contains("error"));
    CHECK(row["scene"] == "grids");
    CHECK(row["width"] == 32);
    CHECK(row["height"] == 24);
    const uint64_t receivers = row["receivers"];  // pixels that see geometry
    CHECK(receivers > 0);
    CHECK(receivers <= 32 * 24);
    CHECK(row["light_samples"] == 256);

    const nlohmann::json& ours = row["ours"];
    for (const char* key : {"sort_s", "hierarchy_build_s", "penumbra_cast_s", "time_s", "samples_memory_bytes",
                            "hierarchy_memory_bytes", "mask_memory_bytes", "bake_total_s", "peak_rss_bytes", "process_cpu_s"})
        CHECK(ours[key].get<double>() >= 0.0);
    CHECK(ours["penumbra_cast_s"].get<double>() > 0.0);
    CHECK(ours["time_s"].get<double>() ==
          Approx(ours["sort_s"].get<double>() + ours["hierarchy_build_s"].get<double>() + ours["penumbra_cast_s"].get<double>()));
    CHECK(ours["hierarchy_memory_bytes"].get<double>() > 0.0);
    // The build column is the first builds' wall time; the thread-seconds of every build stay beside it.
    CHECK(ours["hierarchy_build_s"].get<double>() > 0.0);
    CHECK(ours["hierarchy_build_thread_s"].get<double>() > 0.0);
    CHECK(ours["process_wall_s"].get<double>() >= ours["time_s"].get<double>());
    CHECK(ours["peak_rss_bytes"].get<double>() > 1e6);
    CHECK(ours["threads"] == 2);

    const nlohmann::json& embree = row["embree"];
    CHECK(embree["time_s"].get<double>() > 0.0);
    CHECK(embree["time_s"].get<double>() == Approx(embree["build_s"].get<double>() + embree["trace_s"].get<double>()));
    CHECK(embree["rays"].get<uint64_t>() > 0);
    CHECK(embree["peak_rss_bytes"].get<double>() > 1e6);
    CHECK(row["ratio"].get<double>() == Approx(embree["time_s"].get<double>() / ours["time_s"].get<double>()));
    CHECK(embree["process_wall_s"].get<double>() >= embree["time_s"].get<double>());

    const nlohmann::json& m = row["mismatches"];
    CHECK(m["relations"].get<uint64_t>() == receivers * 256);
    CHECK(m["blocked_ours"].get<uint64_t>() > 0);
    CHECK(m["mismatches"].get<uint64_t>() == m["only_ours"].get<uint64_t>() + m["only_embree"].get<uint64_t>());
    CHECK(m["non_ties"].get<uint64_t>() == 0);
    CHECK(m["ties"] == m["mismatches"]);

    REQUIRE(j["thread_scaling"].size() == 1);
    CHECK(j["thread_scaling"][0]["threads"] == nlohmann::json({1, 2}));
    CHECK(j["thread_scaling"][0]["speedup"].get<double>() > 0.0);
    REQUIRE(j["root_cull"]["cases"].size() == 2);
    for (const auto& c : j["root_cull"]["cases"]) {
        CHECK(c["culled_at_root"].get<double>() == c["triangles"].get<double>());
        // A rate from two timings: reported, never asserted (the machine may be loaded).
        CHECK(c["triangles_per_second_per_core"].get<double>() >= 0.0);
    }

    // The other sections are kept: everything before the generated part (all of the file when
    // it has no markers yet, then the section is appended).
    const std::string head = original.substr(0, original.find(kBegin));
    std::string md = slurp(dir / "BENCHMARKS.md");
    CHECK(md.rfind(head, 0) == 0);
    CHECK(occurrences(md, kBegin) == 1);
    CHECK_THAT(md, Catch::Contains("Reduced-scale validation run") && Catch::Contains("| grids | 32×24 | 256 |") &&
                       Catch::Contains("### Targets") && Catch::Contains("### Root-cull throughput") &&
                       Catch::Contains("Embree/ours, process"));
    CHECK(r.out.find("| grids | 32×24 | 256 |") != std::string::npos);

    // A second run replaces the section in place: text after it survives too.
    std::ofstream(dir / "BENCHMARKS.md", std::ios::app) << "\n## Later section\n\nkept\n";
    RunResult again = runPenumbra(common + " --no-embree --no-cull");
    INFO(again.err);
    REQUIRE(again.exitCode == 0);
    md = slurp(dir / "BENCHMARKS.md");
    CHECK(md.rfind(head, 0) == 0);
    CHECK(occurrences(md, kBegin) == 1);
    CHECK_THAT(md, Catch::EndsWith("## Later section\n\nkept\n"));
    CHECK_THAT(md, !Catch::Contains("### Root-cull throughput"));

    // A file without the section gets it appended after everything it had.
    const std::string bare = "# Benchmarks\n\n## Other\n\ntext\n";
    std::ofstream(dir / "bare.md") << bare;
    RunResult appended = runPenumbra("bench table2 -q --scale 0.05 --rows 640x480@256 --scenes grids --examples " +
                                     std::string(PENUMBRA_SOURCE_DIR) + "/examples --tmp " + dir.path.string() +
                                     " --no-embree --no-cull --markdown " + (dir / "bare.md"));
    REQUIRE(appended.exitCode == 0);
    md = slurp(dir / "bare.md");
    CHECK(md.rfind(bare, 0) == 0);
    CHECK(occurrences(md, kBegin) == 1);
    CHECK_THAT(md, Catch::Contains("## Table 2"));
}

TEST_CASE("bench table2 rejects unknown rows and scenes with one-line errors", "[cli][bench]") {
    RunResult r = runPenumbra("bench table2 --rows 999x1@1");
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.err, Catch::Contains("--rows: unknown row") && Catch::Contains("640x480@256"));
    r = runPenumbra("bench table2 --scenes nowhere --examples /nonexistent");
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.err, Catch::Contains("no scene file"));
    // A scene whose receivers are not a camera: every row's bake failed on "width", exit 0.
    const std::string volume = std::string(PENUMBRA_SOURCE_DIR) + "/examples/volume.json";
    for (const char* bench : {"table2", "methods"}) {
        r = runPenumbra(std::string("bench ") + bench + " -q --scenes " + volume);
        INFO(r.err);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.err, Catch::Contains("--scenes: " + volume + ": the bench sets a camera's image size") &&
                              Catch::Contains("\"volume\""));
    }
    r = runPenumbra("bench methods --render /nonexistent/r.json");
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.err, Catch::Contains("/nonexistent/r.json: cannot open"));
}
