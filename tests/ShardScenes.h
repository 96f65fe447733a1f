#pragma once
// The scene and helpers of the tests of sharded bakes, merges and resume after a kill
// (tests/bake/test_shards.cpp, tests/bake/test_resume.cpp): outputs compared byte for byte.

#include "CliRunner.h"

#include <catch2/catch.hpp>

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace penumbra::test {

// Two lights (so per-light irradiance is merged too), a camera of 3072 receivers.
inline const char* kShardScene = R"({
  "geometry": [{"type": "grid", "cells": 6, "levels": 2, "size": 2, "floor_size": 5, "rotate_step_deg": 20}],
  "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 64, "sample_sets": 4},
             {"type": "disk", "center": [2,3,1], "normal": [-0.5,-1,-0.2], "radius": 0.5, "samples": 32, "sample_sets": 2}],
  "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0.5,0], "width": 64, "height": 48},
  "output": "out/scene.exr"})";

inline void writeText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

/// The bytes a bake of kShardScene in @p dir leaves: its EXR, PNG and the dump in @p dump.
inline std::string shardSceneOutputs(const std::string& dir, const std::string& dump) {
    return slurp(dir + "/out/scene.exr") + "|" + slurp(dir + "/out/scene.png") + "|" + slurp(dump + "/masks.npy") + "|" +
           slurp(dump + "/receivers.npy");
}

/// `penumbra bake ARGS --quiet`, which must succeed.
inline void bakeOk(const std::string& args) {
    RunResult r = runPenumbra("bake " + args + " --quiet");
    INFO("penumbra bake " << args << "\n" << r.err);
    REQUIRE(r.exitCode == 0);
}

struct TiledScene {
    std::string path;
    uint64_t budget = 0;  ///< the smallest --memory-budget that bakes it: 3 or more memory tiles
};

/// kShardScene at 800 x 600 in @p dir, and the budget that cuts it into the most memory tiles.
inline TiledScene tiledShardScene(const ScratchDir& dir) {
    std::string scene = kShardScene;
    const std::string size = "\"width\": 64, \"height\": 48";
    scene.replace(scene.find(size), size.size(), "\"width\": 800, \"height\": 600");
    writeText(dir / "tiled.json", scene);
    TiledScene t{dir / "tiled.json", 0};
    std::filesystem::create_directories(dir / "plan");  // -o names an existing folder
    bakeOk(t.path + " --dump " + dir / "plan" + " -o " + dir / "plan/p.exr --stats " + dir / "plan.json");
    t.budget = nlohmann::json::parse(slurp(dir / "plan.json"))["memory_plan"]["minimum_budget_bytes"].get<uint64_t>();
    // Masks are kept for the dump, as for shards and checkpoints: the same plan.
    bakeOk(t.path + " --dump " + dir / "plan" + " -o " + dir / "plan/p.exr --memory-budget " + std::to_string(t.budget) +
           " --stats " + dir / "plan.json");
    REQUIRE(nlohmann::json::parse(slurp(dir / "plan.json"))["memory_plan"]["tiles"].get<int>() >= 3);
    return t;
}

/// The names of the entries of @p dir (none when it does not exist).
inline std::vector<std::string> filesIn(const std::string& dir) {
    std::vector<std::string> names;
    if (std::filesystem::exists(dir))
        for (const auto& e : std::filesystem::directory_iterator(dir)) names.push_back(e.path().filename().string());
    return names;
}

}  // namespace penumbra::test
