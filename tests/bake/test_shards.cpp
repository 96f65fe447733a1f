// Sharded bakes and their merge (bake/shard, issue #18): the merged outputs must be byte-identical
// to one uninterrupted bake, and every file that does not belong is refused with one line. Resume
// after a kill is tests/bake/test_resume.cpp.

#include "ShardScenes.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <vector>

using namespace penumbra::test;
namespace fs = std::filesystem;

TEST_CASE("merging N shards of either cut gives the unsharded bake's bytes, N = 1..8", "[shards]") {
    ScratchDir dir("shards");
    writeText(dir / "scene.json", kShardScene);
    bakeOk(dir / "scene.json" + " --dump " + dir / "whole");
    const std::string expected = shardSceneOutputs(dir.path.string(), dir / "whole");
    REQUIRE(expected.size() > 10000);
    for (const char* cut : {"receivers", "blockers"})
        for (int n = 1; n <= 8; ++n) {
            const std::string shards = dir / fmt::format("{}-{}", cut, n);
            // Threads differ from shard to shard; the bytes must not.
            for (int i = 0; i < n; ++i)
                bakeOk(dir / "scene.json" + fmt::format(" --shard {}/{} --shard-by {} --shard-dir {}{}", i, n, cut, shards,
                                                      i % 2 ? " --threads 1" : ""));
            CHECK(filesIn(shards).size() == size_t(n));
            fs::remove_all(dir / "out");
            RunResult merge = runPenumbra("merge " + dir / "scene.json" + " --shard-dir " + shards + " --quiet --dump " + dir / "merged");
            INFO(cut << " " << n << ": " << merge.err);
            REQUIRE(merge.exitCode == 0);
            CHECK(shardSceneOutputs(dir.path.string(), dir / "merged") == expected);
            CHECK_FALSE(hasTempFiles(dir.path));
        }
}

TEST_CASE("the automatic cut shards a method without memory tiles by blockers", "[shards]") {
    // auto chose receivers for 2 shards of 12,288 receivers whatever the method, and a bake with
    // --method embree was then refused: only hpc casts by receivers.
    ScratchDir dir("shards-auto");
    std::string scene = kShardScene;
    const std::string size = "\"width\": 64, \"height\": 48";
    scene.replace(scene.find(size), size.size(), "\"width\": 128, \"height\": 96");
    writeText(dir / "scene.json", scene);
    bakeOk(dir / "scene.json" + " --method embree --dump " + dir / "whole");
    const std::string expected = shardSceneOutputs(dir.path.string(), dir / "whole");
    for (int i = 0; i < 2; ++i) bakeOk(dir / "scene.json" + fmt::format(" --method embree --shard {}/2 --shard-dir {}", i, dir / "s"));
    fs::remove_all(dir / "out");
    const RunResult merge = runPenumbra("merge " + dir / "scene.json" + " --method embree --shard-dir " + dir / "s" + " --quiet --dump " +
                                        dir / "merged");
    INFO(merge.err);
    REQUIRE(merge.exitCode == 0);
    CHECK(shardSceneOutputs(dir.path.string(), dir / "merged") == expected);
}

TEST_CASE("by-receivers shards with memory tiles and threads merge to the same bytes", "[shards]") {
    ScratchDir dir("shards-tiles");
    const auto [scene, budget] = tiledShardScene(dir);
    bakeOk(scene + " --dump " + dir / "whole");
    const std::string expected = shardSceneOutputs(dir.path.string(), dir / "whole");
    for (int i = 0; i < 3; ++i)
        bakeOk(scene + fmt::format(" --shard {}/3 --shard-by receivers --shard-dir {} --threads {}{}", i, dir / "s", i + 1,
                                 i == 1 ? " --memory-budget " + std::to_string(budget) : ""));
    fs::remove_all(dir / "out");
    RunResult merge = runPenumbra("merge " + scene + " --shard-dir " + dir / "s" + " --quiet --dump " + dir / "merged");
    REQUIRE(merge.exitCode == 0);
    CHECK(shardSceneOutputs(dir.path.string(), dir / "merged") == expected);
}

TEST_CASE("a by-receivers shard's memory tiles cut its own share of the receivers", "[shards]") {
    // Cut as if it held every receiver, each shard took as many tiles as a shard of them all.
    ScratchDir dir("shards-plan");
    const TiledScene tiled = tiledShardScene(dir);  // no structured binding: lambdas capture it (clang)
    const std::string scene = tiled.path;
    const std::string options = " --shard-by receivers --memory-budget " + std::to_string(tiled.budget) + " --stats " + dir / "s.json";
    auto tilesOf = [&](const std::string& shard) {
        bakeOk(scene + " --shard " + shard + " --shard-dir " + dir / ("s" + shard.substr(2)) + options);
        return nlohmann::json::parse(slurp(dir / "s.json"))["memory_plan"]["tiles"].get<int>();
    };
    const int one = tilesOf("0/1"), four = tilesOf("0/4");
    INFO("tiles of shard 0/1: " << one << ", of shard 0/4: " << four);
    CHECK(one >= 3);
    CHECK(four < one);
}

TEST_CASE("a by-receivers shard keeps masks for its share only, under a budget the whole bake's masks exceed", "[shards]") {
    // Every receiver's masks were kept in each shard: its minimum budget did not fall with N.
    ScratchDir dir("shards-share-masks");
    const TiledScene tiled = tiledShardScene(dir);  // no structured binding: lambdas capture it (clang)
    const std::string scene = tiled.path;
    auto planOf = [&](const std::string& shard) {
        bakeOk(scene + " --shard " + shard + " --shard-by receivers --shard-dir " + dir / "plan-shards" + " --stats " + dir / "s.json");
        return nlohmann::json::parse(slurp(dir / "s.json"));
    };
    const nlohmann::json one = planOf("0/1"), four = planOf("0/4");
    const uint64_t receivers = one["receivers"].get<uint64_t>();
    const uint64_t all = one["memory_plan"]["minimum_budget_bytes"].get<uint64_t>();
    const uint64_t share = four["memory_plan"]["minimum_budget_bytes"].get<uint64_t>();
    INFO(receivers << " receivers: shard 0/1 needs " << all << " bytes, shard 0/4 " << share);
    REQUIRE(all == tiled.budget);  // two groups of 8 bytes per receiver, as for a dump
    CHECK(all - share >= 7 * receivers);  // a quarter of 16 bytes and a 4-byte row index each
    // Every shard of four bakes below what one holding every receiver's masks needs, and they
    // merge to the unsharded bytes.
    bakeOk(scene + " --dump " + dir / "whole" + " -o " + dir / "whole.exr");
    for (int i = 0; i < 4; ++i)
        bakeOk(scene + fmt::format(" --shard {}/4 --shard-by receivers --shard-dir {} --memory-budget {}", i, dir / "s", all - 1));
    const RunResult merge = runPenumbra("merge " + scene + " --shard-dir " + dir / "s" + " --quiet --dump " + dir / "merged" + " -o " +
                                        dir / "merged.exr");
    INFO(merge.err);
    REQUIRE(merge.exitCode == 0);
    CHECK(slurp(dir / "merged/masks.npy") == slurp(dir / "whole/masks.npy"));
    CHECK(slurp(dir / "merged.exr") == slurp(dir / "whole.exr"));
}

TEST_CASE("a merge casts an antialiased camera's refinement itself, to the same bytes", "[shards]") {
    ScratchDir dir("shards-aa");
    writeText(dir / "aa.json", R"({
      "geometry": [{"type": "grid", "size": 3, "cells": 12, "bar": 0.3, "thickness": 0.05, "levels": 1, "height": 0.8, "floor_size": 8}],
      "lights": [{"type": "rect", "center": [0, 5, 0], "u": [0.4, 0, 0], "v": [0, 0, 0.4], "samples": 64, "sample_sets": 4}],
      "receivers": {"type": "camera", "eye": [0, 4.5, 6], "target": [0, 0.4, 0], "width": 96, "height": 72,
                    "antialias": {"threshold": 0.1, "samples": 4}},
      "output": "out/scene.exr"})");
    const std::string scene = dir / "aa.json";
    bakeOk(scene + " --dump " + dir / "whole" + " --stats " + dir / "whole.json");
    REQUIRE(nlohmann::json::parse(slurp(dir / "whole.json"))["antialias"]["refined_pixels"].get<int>() > 0);
    const std::string expected = shardSceneOutputs(dir.path.string(), dir / "whole");
    for (const char* cut : {"receivers", "blockers"}) {
        const std::string shards = dir / cut;
        for (int i = 0; i < 3; ++i) bakeOk(scene + fmt::format(" --shard {}/3 --shard-by {} --shard-dir {}", i, cut, shards));
        fs::remove_all(dir / "out");
        RunResult merge = runPenumbra("merge " + scene + " --shard-dir " + shards + " --quiet --dump " + dir / "merged");
        INFO(cut << ": " << merge.err);
        REQUIRE(merge.exitCode == 0);
        CHECK(shardSceneOutputs(dir.path.string(), dir / "merged") == expected);
    }
}

TEST_CASE("merge refuses other scenes, other settings, missing, duplicate and truncated shards", "[shards][cli]") {
    ScratchDir dir("shards-bad");
    writeText(dir / "scene.json", kShardScene);
    std::string other = kShardScene;
    other.replace(other.find("\"samples\": 32"), 13, "\"samples\": 16");
    writeText(dir / "other.json", other);
    const std::string scene = dir / "scene.json";
    for (int i = 0; i < 3; ++i) bakeOk(scene + fmt::format(" --shard {}/3 --shard-by blockers --shard-dir {}", i, dir / "good"));
    auto merge = [&](const std::string& shards) { return runPenumbra("merge " + scene + " --shard-dir " + shards + " --quiet"); };
    auto copyGood = [&](const std::string& to) {
        fs::copy(dir / "good", to);
        return to;
    };
    REQUIRE(merge(dir / "good").exitCode == 0);

    SECTION("a method without masks, named as the merge's (no --checkpoint was given)") {
        const RunResult r = runPenumbra("merge " + scene + " --shard-dir " + dir / "good" + " --method penumbra-map --quiet");
        requireCleanError(r, "merge: --method penumbra-map gives visible fractions, not per-sample masks to merge");
    }

    SECTION("a shard of another scene") {
        const std::string s = copyGood(dir / "s");
        bakeOk(dir / "other.json" + " --shard 1/3 --shard-by blockers --shard-dir " + dir / "o");
        fs::copy_file(dir / "o/shard-1-of-3.pnpart", s + "/shard-1-of-3.pnpart", fs::copy_options::overwrite_existing);
        requireCleanError(merge(s), "shard of another scene file");
    }
    SECTION("a shard of other settings: another cut, another count, another method") {
        const std::string s = copyGood(dir / "s");
        bakeOk(scene + " --shard 1/3 --shard-by receivers --shard-dir " + dir / "r");
        fs::copy_file(dir / "r/shard-1-of-3.pnpart", s + "/shard-1-of-3.pnpart", fs::copy_options::overwrite_existing);
        requireCleanError(merge(s), "cut by receivers");
        const std::string t = copyGood(dir / "t");
        bakeOk(scene + " --shard 1/4 --shard-by blockers --shard-dir " + dir / "four");
        fs::copy_file(dir / "four/shard-1-of-4.pnpart", t + "/shard-1-of-4.pnpart");
        requireCleanError(merge(t), "shard 1 of 4");
        const std::string u = copyGood(dir / "u");
        bakeOk(scene + " --shard 1/3 --shard-by blockers --method reference --shard-dir " + dir / "ref");
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
        // Bytes appended before the checksum: too long, not "truncated" (the masks end early).
        {
            std::vector<char> bytes(size);
            std::ifstream(dir / "good/shard-0-of-3.pnpart", std::ios::binary).read(bytes.data(), std::streamsize(size));
            bytes.insert(bytes.end() - 8, 16, '\0');
            std::ofstream(file, std::ios::binary | std::ios::trunc).write(bytes.data(), std::streamsize(bytes.size()));
        }
        requireCleanError(merge(s), "16 bytes after the masks");
    }
    CHECK_FALSE(fs::exists(dir / "out/scene.exr.tmp"));
    CHECK_FALSE(hasTempFiles(dir.path));
}

TEST_CASE("bad --shard values are one-line errors", "[shards][cli]") {
    ScratchDir dir("shards-args");
    writeText(dir / "scene.json", kShardScene);
    const std::string scene = dir / "scene.json";
    requireCleanError(runPenumbra("bake " + scene + " --shard 3/3 --shard-dir " + dir / "s"), "--shard");
    const RunResult malformed = runPenumbra("bake " + scene + " --shard x --shard-dir " + dir / "s");  // a usage error
    CHECK(malformed.exitCode == 2);
    CHECK_THAT(malformed.err, Catch::StartsWith("penumbra: error: --shard: 'x' is not I/N"));
    requireCleanError(runPenumbra("bake " + scene + " --shard 0/2"), "--shard-dir");
    requireCleanError(runPenumbra("bake " + scene + " --checkpoint-every 5"), "--checkpoint-every: needs --checkpoint DIR");
    requireCleanError(runPenumbra("bake " + scene + " --checkpoint " + dir / "c" + " --checkpoint-every -1"),
                      "--checkpoint-every: must be a number of seconds");
    requireCleanError(runPenumbra("bake " + scene + " --shard slurm --shard-dir " + dir / "s", "env -u SLURM_ARRAY_TASK_ID -u SLURM_ARRAY_TASK_COUNT -u SLURM_ARRAY_TASK_MIN"),
                      "is not set (not a task of a Slurm job array)");
    RunResult r = runPenumbra("bake " + scene + " --shard slurm --shard-dir " + dir / "s" + " --quiet",
                              "SLURM_ARRAY_TASK_ID=1 SLURM_ARRAY_TASK_COUNT=2");
    REQUIRE(r.exitCode == 0);
    CHECK(fs::exists(dir / "s/shard-1-of-2.pnpart"));
}
