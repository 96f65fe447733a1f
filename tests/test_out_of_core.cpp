// Out of core: peak memory does not grow with the triangle count, bucket files never outlive a
// bake (success, error, full disk, SIGTERM), and streamed-and-bucketed bakes of the same geometry
// from OBJ, glTF and .ptri agree bit for bit with the in-memory reference.

#include "CliRunner.h"

#include "stream/Npy.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <csignal>
#include <thread>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// Receivers see a floor and a grid; `blades` grass blades stand far outside the light's reach,
/// so they stream through every stage but are culled at the hierarchy root.
std::string grassScene(uint64_t blades, bool cullBeforeSpill = true) {
    nlohmann::json s = {
        {"geometry",
         {{{"type", "grid"}, {"levels", 1}, {"cells", 8}, {"size", 3}, {"floor_size", 8}},
          {{"type", "grass"}, {"count", blades}, {"area", {{40, 40}, {140, 140}}}, {"seed", 3}}}},
        {"lights", {{{"type", "rect"}, {"center", {0, 5, 0}}, {"u", {1.5, 0, 0}}, {"v", {0, 0, 1.5}}, {"samples", 64}}}},
        {"receivers", {{"type", "camera"}, {"eye", {0, 5, 7}}, {"target", {0, 0.5, 0}}, {"width", 160}, {"height", 120}}},
        {"output", "out.exr"},
        {"bake", {{"cull_before_spill", cullBeforeSpill}}}};
    return s.dump();
}

nlohmann::json bakeStats(const ScratchDir& dir, const std::string& scene, const std::string& extra, const std::string& prefix = "") {
    std::ofstream(dir / "scene.json") << scene;
    RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q --tmp " + dir.path.string() + " --stats " + (dir / "stats.json") + " " + extra,
                              prefix);
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    return nlohmann::json::parse(slurp(dir / "stats.json"));
}

/// True while process @p pid holds a bucket file open. Bucket files are anonymous (O_TMPFILE)
/// and their directory is removed once they are open, so /proc is where they can be seen.
bool holdsBucketFiles(pid_t pid) {
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec)) {
        std::string target = std::filesystem::read_symlink(e.path(), ec).string();
        if (target.find("penumbra-buckets") != std::string::npos) return true;
    }
    return false;
}

bool anyBucketDirectory(const std::filesystem::path& dir) {
    for (const auto& e : std::filesystem::directory_iterator(dir))
        if (e.path().filename().string().rfind("penumbra-buckets", 0) == 0) return true;
    return false;
}

}  // namespace

TEST_CASE("peak RSS is the same for 1M and 10M streamed triangles", "[outofcore]") {
    ScratchDir small("ooc-1m"), large("ooc-10m");
    // Grass blades have 5 triangles by default: 200K and 2M blades.
    nlohmann::json a = bakeStats(small, grassScene(200'000, false), "");
    // 10M triangles are 400 MB as records; the bake must run in a 256 MiB address space.
    nlohmann::json b = bakeStats(large, grassScene(2'000'000, false), "", "prlimit --as=268435456");
    const uint64_t trianglesA = a["counters"]["triangles_read"], trianglesB = b["counters"]["triangles_read"];
    CHECK(trianglesA > 1'000'000);
    CHECK(trianglesB > 10'000'000);
    CHECK(b["buckets"]["bytes_written"].get<uint64_t>() == 40 * trianglesB);  // every triangle went through disk
    const double rssA = a["counters"]["peak_rss_bytes"], rssB = b["counters"]["peak_rss_bytes"];
    INFO("peak RSS 1M: " << rssA / 1e6 << " MB, 10M: " << rssB / 1e6 << " MB");
    CHECK(std::abs(rssB - rssA) < 0.10 * rssA);
    CHECK_FALSE(anyBucketDirectory(small.path));
    CHECK_FALSE(anyBucketDirectory(large.path));
}

TEST_CASE("bucket files stay with --keep-buckets and only then", "[outofcore]") {
    ScratchDir dir("keep");
    bakeStats(dir, grassScene(1000), "--keep-buckets");
    CHECK(anyBucketDirectory(dir.path));
}

TEST_CASE("a full disk while bucketing fails cleanly and removes the buckets", "[outofcore]") {
    ScratchDir dir("fsize-buckets");
    std::ofstream(dir / "scene.json") << grassScene(50'000, false);
    RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q --tmp " + dir.path.string(), "prlimit --fsize=100000");
    INFO(r.err);
    CHECK(r.exitCode == 1);
    CHECK(lineCount(r.err) == 1);
    CHECK_THAT(r.err, Catch::Contains("penumbra-buckets") && Catch::Contains("more bytes"));
    CHECK_FALSE(anyBucketDirectory(dir.path));
}

TEST_CASE("SIGTERM during a bake removes the bucket files", "[outofcore]") {
    ScratchDir dir("sigterm");
    std::ofstream(dir / "scene.json") << grassScene(3'000'000, false);
    std::string cmd = std::string(PENUMBRA_BINARY) + " bake " + (dir / "scene.json") + " -q --tmp " + dir.path.string() +
                      " >/dev/null 2>&1 & echo $! > " + (dir / "pid");
    REQUIRE(std::system(cmd.c_str()) == 0);
    pid_t pid = 0;
    for (int i = 0; i < 100 && pid == 0; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        pid = std::atoi(slurp(dir / "pid").c_str());
    }
    REQUIRE(pid > 0);
    bool sawBuckets = false;
    for (int i = 0; i < 600 && !sawBuckets; ++i) {  // up to 30 s for the scan pass to finish
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        sawBuckets = holdsBucketFiles(pid);
    }
    REQUIRE(sawBuckets);
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    REQUIRE(::kill(pid, SIGTERM) == 0);
    for (int i = 0; i < 200 && ::kill(pid, 0) == 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    CHECK(::kill(pid, 0) != 0);  // it exited
    CHECK_FALSE(anyBucketDirectory(dir.path));
    CHECK(dir.entries() == std::vector<std::string>{"pid", "scene.json"});  // nothing else left behind
}

TEST_CASE("streamed and bucketed bakes from OBJ, glTF and .ptri agree with the in-memory reference", "[outofcore]") {
    ScratchDir dir("formats");
    std::ofstream(dir / "gen.json") << R"({
      "geometry": [{"type": "grid", "cells": 4, "levels": 2, "size": 2, "floor_size": 5},
                   {"type": "grass", "count": 300, "area": [[-2,-2],[2,2]], "seed": 5}],
      "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1]}],
      "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0.5,0]}})";
    std::vector<std::string> dumps;
    for (const char* ext : {"obj", "glb", "ptri"}) {
        std::string geometry = dir / (std::string("scene.") + ext);
        RunResult g = runPenumbra("generate " + (dir / "gen.json") + " -o " + geometry);
        INFO(g.err);
        REQUIRE(g.exitCode == 0);
        nlohmann::json s = {
            {"geometry", {{{"type", "file"}, {"path", geometry}}}},
            {"lights", {{{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}, {"samples", 64}, {"sample_sets", 4}}}},
            {"receivers", {{"type", "camera"}, {"eye", {0, 4, 5}}, {"target", {0, 0.5, 0}}, {"width", 48}, {"height", 36}}},
            {"output", std::string("out-") + ext + ".exr"}};
        std::ofstream(dir / "bake.json") << s.dump();
        std::string hpc = dir / (std::string("hpc-") + ext);
        REQUIRE(runPenumbra("bake " + (dir / "bake.json") + " -q --tmp " + dir.path.string() + " --dump " + hpc).exitCode == 0);
        dumps.push_back(hpc);
        if (dumps.size() == 1) {
            RunResult ref = runPenumbra("bake " + (dir / "bake.json") + " -q --method reference --disable sort -o " + (dir / "ref.exr") +
                                        " --dump " + (dir / "ref"));
            REQUIRE(ref.exitCode == 0);
        }
    }
    for (const std::string& d : dumps) {
        RunResult cmp = runPenumbra("compare " + (dir / "ref") + " " + d);
        INFO(d << "\n" << cmp.out);
        CHECK(cmp.exitCode == 0);
        CHECK(readNpy(d + "/masks.npy").data == readNpy(dir / "ref/masks.npy").data);
    }
    CHECK_FALSE(anyBucketDirectory(dir.path));
}

TEST_CASE("corrupt .ptri and malformed glTF inputs fail cleanly without leftovers", "[outofcore]") {
    ScratchDir dir("corrupt");
    std::ofstream(dir / "gen.json") << R"({
      "geometry": [{"type": "grid", "cells": 4, "levels": 2}],
      "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1]}],
      "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0.5,0]}})";
    REQUIRE(runPenumbra("generate " + (dir / "gen.json") + " -o " + (dir / "g.ptri")).exitCode == 0);
    std::string bytes = slurp(dir / "g.ptri");
    std::ofstream(dir / "truncated.ptri", std::ios::binary) << bytes.substr(0, bytes.size() - 100);
    bytes[bytes.size() / 2] ^= 0x55;
    std::ofstream(dir / "corrupt.ptri", std::ios::binary) << bytes;
    std::vector<std::string> inputs = {dir / "truncated.ptri", dir / "corrupt.ptri"};
    for (const auto& e : std::filesystem::directory_iterator(sharedData("gltf/BoundsChecking"))) inputs.push_back(e.path().string());
    for (const std::string& input : inputs) {
        nlohmann::json s = {
            {"geometry", {{{"type", "file"}, {"path", input}}}},
            {"lights", {{{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}}}},
            {"receivers", {{"type", "camera"}, {"eye", {0, 4, 5}}, {"target", {0, 0.5, 0}}, {"width", 16}, {"height", 12}}},
            {"output", "x.exr"}};
        std::ofstream(dir / "bake.json") << s.dump();
        RunResult r = runPenumbra("bake " + (dir / "bake.json") + " -q --tmp " + dir.path.string());
        INFO(input << ": " << r.err);
        CHECK(r.exitCode == 1);
        CHECK(lineCount(r.err) == 1);
        CHECK_THAT(r.err, Catch::Contains(std::filesystem::path(input).filename().string()));
        CHECK_FALSE(anyBucketDirectory(dir.path));
        CHECK_FALSE(std::filesystem::exists(dir / "x.exr"));
    }
}
