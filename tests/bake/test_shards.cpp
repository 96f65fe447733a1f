// Sharded bakes and their merge (bake/shard, issue #18), and resume after a kill (#20): the
// merged or resumed outputs must be byte-identical to one uninterrupted bake, and every file that
// does not belong is refused with one line.

#include "CliRunner.h"

#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include <filesystem>

using namespace penumbra::test;
namespace fs = std::filesystem;

namespace {

// Two lights (so per-light irradiance is merged too), a camera of 3072 receivers.
const char* kScene = R"({
  "geometry": [{"type": "grid", "cells": 6, "levels": 2, "size": 2, "floor_size": 5, "rotate_step_deg": 20}],
  "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 64, "sample_sets": 4},
             {"type": "disk", "center": [2,3,1], "normal": [-0.5,-1,-0.2], "radius": 0.5, "samples": 32, "sample_sets": 2}],
  "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0.5,0], "width": 64, "height": 48},
  "output": "out/scene.exr"})";

void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

/// The bytes a bake leaves: its EXR, PNG and dump.
std::string outputs(const std::string& dir, const std::string& dump) {
    return slurp(dir + "/out/scene.exr") + "|" + slurp(dir + "/out/scene.png") + "|" + slurp(dump + "/masks.npy") + "|" +
           slurp(dump + "/receivers.npy");
}

int bake(const std::string& args) {
    RunResult r = runPenumbra("bake " + args + " --quiet");
    INFO("penumbra bake " << args << "\n" << r.err);
    REQUIRE(r.exitCode == 0);
    return r.exitCode;
}

struct TiledScene {
    std::string path;
    uint64_t budget = 0;  ///< the smallest --memory-budget that bakes it: 3 or more memory tiles
};

/// The scene at 800 x 600, and the budget that cuts it into the most memory tiles.
TiledScene tiledScene(const ScratchDir& dir) {
    std::string scene = kScene;
    const std::string size = "\"width\": 64, \"height\": 48";
    scene.replace(scene.find(size), size.size(), "\"width\": 800, \"height\": 600");
    write(dir / "tiled.json", scene);
    TiledScene t{dir / "tiled.json", 0};
    fs::create_directories(dir / "plan");  // -o names an existing folder
    bake(t.path + " --dump " + dir / "plan" + " -o " + dir / "plan/p.exr --stats " + dir / "plan.json");
    t.budget = nlohmann::json::parse(slurp(dir / "plan.json"))["memory_plan"]["minimum_budget_bytes"].get<uint64_t>();
    // Masks are kept for the dump, as for shards and checkpoints: the same plan.
    bake(t.path + " --dump " + dir / "plan" + " -o " + dir / "plan/p.exr --memory-budget " + std::to_string(t.budget) +
         " --stats " + dir / "plan.json");
    REQUIRE(nlohmann::json::parse(slurp(dir / "plan.json"))["memory_plan"]["tiles"].get<int>() >= 3);
    return t;
}

std::vector<std::string> filesIn(const std::string& dir) {
    std::vector<std::string> names;
    if (fs::exists(dir))
        for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
    return names;
}

}  // namespace

TEST_CASE("merging N shards of either cut gives the unsharded bake's bytes, N = 1..8", "[shards]") {
    ScratchDir dir("shards");
    write(dir / "scene.json", kScene);
    bake(dir / "scene.json" + " --dump " + dir / "whole");
    const std::string expected = outputs(dir.path.string(), dir / "whole");
    REQUIRE(expected.size() > 10000);
    for (const char* cut : {"receivers", "blockers"})
        for (int n = 1; n <= 8; ++n) {
            const std::string shards = dir / fmt::format("{}-{}", cut, n);
            // Threads differ from shard to shard; the bytes must not.
            for (int i = 0; i < n; ++i)
                bake(dir / "scene.json" + fmt::format(" --shard {}/{} --shard-by {} --shard-dir {}{}", i, n, cut, shards,
                                                      i % 2 ? " --threads 1" : ""));
            CHECK(filesIn(shards).size() == size_t(n));
            fs::remove_all(dir / "out");
            RunResult merge = runPenumbra("merge " + dir / "scene.json" + " --shard-dir " + shards + " --quiet --dump " + dir / "merged");
            INFO(cut << " " << n << ": " << merge.err);
            REQUIRE(merge.exitCode == 0);
            CHECK(outputs(dir.path.string(), dir / "merged") == expected);
            CHECK_FALSE(hasTempFiles(dir.path));
        }
}

TEST_CASE("by-receivers shards with memory tiles and threads merge to the same bytes", "[shards]") {
    ScratchDir dir("shards-tiles");
    const auto [scene, budget] = tiledScene(dir);
    bake(scene + " --dump " + dir / "whole");
    const std::string expected = outputs(dir.path.string(), dir / "whole");
    for (int i = 0; i < 3; ++i)
        bake(scene + fmt::format(" --shard {}/3 --shard-by receivers --shard-dir {} --threads {}{}", i, dir / "s", i + 1,
                                 i == 1 ? " --memory-budget " + std::to_string(budget) : ""));
    fs::remove_all(dir / "out");
    RunResult merge = runPenumbra("merge " + scene + " --shard-dir " + dir / "s" + " --quiet --dump " + dir / "merged");
    REQUIRE(merge.exitCode == 0);
    CHECK(outputs(dir.path.string(), dir / "merged") == expected);
}

TEST_CASE("a merge casts an antialiased camera's refinement itself, to the same bytes", "[shards]") {
    ScratchDir dir("shards-aa");
    write(dir / "aa.json", R"({
      "geometry": [{"type": "grid", "size": 3, "cells": 12, "bar": 0.3, "thickness": 0.05, "levels": 1, "height": 0.8, "floor_size": 8}],
      "lights": [{"type": "rect", "center": [0, 5, 0], "u": [0.4, 0, 0], "v": [0, 0, 0.4], "samples": 64, "sample_sets": 4}],
      "receivers": {"type": "camera", "eye": [0, 4.5, 6], "target": [0, 0.4, 0], "width": 96, "height": 72,
                    "antialias": {"threshold": 0.1, "samples": 4}},
      "output": "out/scene.exr"})");
    const std::string scene = dir / "aa.json";
    bake(scene + " --dump " + dir / "whole" + " --stats " + dir / "whole.json");
    REQUIRE(nlohmann::json::parse(slurp(dir / "whole.json"))["antialias"]["refined_pixels"].get<int>() > 0);
    const std::string expected = outputs(dir.path.string(), dir / "whole");
    for (const char* cut : {"receivers", "blockers"}) {
        const std::string shards = dir / cut;
        for (int i = 0; i < 3; ++i) bake(scene + fmt::format(" --shard {}/3 --shard-by {} --shard-dir {}", i, cut, shards));
        fs::remove_all(dir / "out");
        RunResult merge = runPenumbra("merge " + scene + " --shard-dir " + shards + " --quiet --dump " + dir / "merged");
        INFO(cut << ": " << merge.err);
        REQUIRE(merge.exitCode == 0);
        CHECK(outputs(dir.path.string(), dir / "merged") == expected);
    }
}

TEST_CASE("merge refuses other scenes, other settings, missing, duplicate and truncated shards", "[shards][cli]") {
    ScratchDir dir("shards-bad");
    write(dir / "scene.json", kScene);
    std::string other = kScene;
    other.replace(other.find("\"samples\": 32"), 13, "\"samples\": 16");
    write(dir / "other.json", other);
    const std::string scene = dir / "scene.json";
    for (int i = 0; i < 3; ++i) bake(scene + fmt::format(" --shard {}/3 --shard-by blockers --shard-dir {}", i, dir / "good"));
    auto merge = [&](const std::string& shards) { return runPenumbra("merge " + scene + " --shard-dir " + shards + " --quiet"); };
    auto copyGood = [&](const std::string& to) {
        fs::copy(dir / "good", to);
        return to;
    };
    REQUIRE(merge(dir / "good").exitCode == 0);

    SECTION("a shard of another scene") {
        const std::string s = copyGood(dir / "s");
        bake(dir / "other.json" + " --shard 1/3 --shard-by blockers --shard-dir " + dir / "o");
        fs::copy_file(dir / "o/shard-1-of-3.pnpart", s + "/shard-1-of-3.pnpart", fs::copy_options::overwrite_existing);
        requireCleanError(merge(s), "shard of another scene file");
    }
    SECTION("a shard of other settings: another cut, another count, another method") {
        const std::string s = copyGood(dir / "s");
        bake(scene + " --shard 1/3 --shard-by receivers --shard-dir " + dir / "r");
        fs::copy_file(dir / "r/shard-1-of-3.pnpart", s + "/shard-1-of-3.pnpart", fs::copy_options::overwrite_existing);
        requireCleanError(merge(s), "cut by receivers");
        const std::string t = copyGood(dir / "t");
        bake(scene + " --shard 1/4 --shard-by blockers --shard-dir " + dir / "four");
        fs::copy_file(dir / "four/shard-1-of-4.pnpart", t + "/shard-1-of-4.pnpart");
        requireCleanError(merge(t), "shard 1 of 4");
        const std::string u = copyGood(dir / "u");
        bake(scene + " --shard 1/3 --shard-by blockers --method reference --shard-dir " + dir / "ref");
        fs::copy_file(dir / "ref/shard-1-of-3.pnpart", u + "/shard-1-of-3.pnpart", fs::copy_options::overwrite_existing);
        requireCleanError(merge(u), "other settings");
    }
    SECTION("a missing shard, and an empty directory") {
        const std::string s = copyGood(dir / "s");
        fs::remove(s + "/shard-1-of-3.pnpart");
        requireCleanError(merge(s), "missing 1 of 3 shards (1)");
        fs::create_directory(dir / "empty");
        requireCleanError(merge(dir / "empty"), "no shard files");
    }
    SECTION("a duplicate shard") {
        const std::string s = copyGood(dir / "s");
        fs::copy_file(s + "/shard-2-of-3.pnpart", s + "/shard-2-of-3-retry.pnpart");
        requireCleanError(merge(s), "duplicate of shard 2 of 3");
    }
    SECTION("truncated and damaged shards") {
        const std::string s = copyGood(dir / "s");
        const std::string file = s + "/shard-0-of-3.pnpart";
        const uintmax_t size = fs::file_size(file);
        for (uintmax_t cut : {uintmax_t(0), uintmax_t(5), uintmax_t(60), size / 2, size - 1}) {
            fs::copy_file(dir / "good/shard-0-of-3.pnpart", file, fs::copy_options::overwrite_existing);
            fs::resize_file(file, cut);
            RunResult r = merge(s);
            INFO("cut at " << cut);
            requireCleanError(r, "shard-0-of-3.pnpart");
        }
        fs::copy_file(dir / "good/shard-0-of-3.pnpart", file, fs::copy_options::overwrite_existing);
        {
            std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
            f.seekp(std::streamoff(size - 20));
            f.put('\x5a');
        }
        requireCleanError(merge(s), "checksum mismatch");
    }
    CHECK_FALSE(fs::exists(dir / "out/scene.exr.tmp"));
    CHECK_FALSE(hasTempFiles(dir.path));
}

TEST_CASE("bad --shard values are one-line errors", "[shards][cli]") {
    ScratchDir dir("shards-args");
    write(dir / "scene.json", kScene);
    const std::string scene = dir / "scene.json";
    requireCleanError(runPenumbra("bake " + scene + " --shard 3/3 --shard-dir " + dir / "s"), "--shard");
    requireCleanError(runPenumbra("bake " + scene + " --shard x --shard-dir " + dir / "s"), "--shard");
    requireCleanError(runPenumbra("bake " + scene + " --shard 0/2"), "--shard-dir");
    requireCleanError(runPenumbra("bake " + scene + " --shard slurm --shard-dir " + dir / "s", "env -u SLURM_ARRAY_TASK_ID -u SLURM_ARRAY_TASK_COUNT -u SLURM_ARRAY_TASK_MIN"),
                      "is not set (not a task of a Slurm job array)");
    RunResult r = runPenumbra("bake " + scene + " --shard slurm --shard-dir " + dir / "s" + " --quiet",
                              "SLURM_ARRAY_TASK_ID=1 SLURM_ARRAY_TASK_COUNT=2");
    REQUIRE(r.exitCode == 0);
    CHECK(fs::exists(dir / "s/shard-1-of-2.pnpart"));
}

TEST_CASE("a bake killed with SIGKILL after some memory tiles resumes to the same bytes", "[shards][resume]") {
    ScratchDir dir("resume");
    const auto [scene, budget] = tiledScene(dir);
    const std::string common = " --memory-budget " + std::to_string(budget) + " --threads 2 --dump " + dir / "dump";
    bake(scene + common);
    const std::string expected = outputs(dir.path.string(), dir / "dump");
    auto clean = [&] { fs::remove_all(dir / "out"), fs::remove_all(dir / "dump"); };
    clean();
    const std::string command = "bake " + scene + common + " --checkpoint " + dir / "ckpt" + " --quiet";

    // Killed after 1 tile, then again after 2 more, then the same command finishes the bake.
    for (int after : {1, 2}) {
        RunResult killed = runPenumbra(command, fmt::format("PENUMBRA_TEST_KILL_AFTER_TILES={}", after));
        REQUIRE(killed.exitCode == 128 + 9);
        CHECK(filesIn(dir / "ckpt").size() == size_t(after == 1 ? 1 : 3));
        CHECK_FALSE(fs::exists(dir / "out/scene.exr"));
    }
    RunResult resumed = runPenumbra(command);
    INFO(resumed.err);
    REQUIRE(resumed.exitCode == 0);
    CHECK(outputs(dir.path.string(), dir / "dump") == expected);
    CHECK(filesIn(dir / "ckpt").empty());  // the bake is complete: its checkpoints are gone
    CHECK_FALSE(hasTempFiles(dir.path));
    clean();

    // A damaged checkpoint: --resume refuses it, --checkpoint ignores it with a note.
    REQUIRE(runPenumbra(command, "PENUMBRA_TEST_KILL_AFTER_TILES=1").exitCode == 137);
    const std::vector<std::string> files = filesIn(dir / "ckpt");
    REQUIRE(files.size() == 1);
    const std::string file = dir / ("ckpt/" + files[0]);
    fs::resize_file(file, fs::file_size(file) - 3);
    requireCleanError(runPenumbra("bake " + scene + common + " --quiet --resume " + dir / "ckpt"), "truncated");

    // A checkpoint of another scene is never used.
    std::string other = slurp(scene);
    other.replace(other.find("\"radius\": 0.5"), 13, "\"radius\": 0.6");
    write(dir / "other.json", other);
    REQUIRE(runPenumbra(command, "PENUMBRA_TEST_KILL_AFTER_TILES=1").exitCode == 137);  // a sound one again
    requireCleanError(runPenumbra("bake " + dir / "other.json" + common + " --quiet --resume " + dir / "ckpt"), "another scene");

    fs::resize_file(file, fs::file_size(file) - 3);
    RunResult noted = runPenumbra("bake " + scene + common + " --checkpoint " + dir / "ckpt");
    REQUIRE(noted.exitCode == 0);
    CHECK_THAT(noted.err, Catch::Contains("ignoring the checkpoint"));
    CHECK(outputs(dir.path.string(), dir / "dump") == expected);
    CHECK_FALSE(hasTempFiles(dir.path));
}
