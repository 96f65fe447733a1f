// The memory plan: tiles chosen to fit --memory-budget, and a clear error naming the smallest
// budget that would work.

#include "CliRunner.h"

#include "bake/MemoryPlan.h"
#include "stream/Error.h"
#include "stream/Memory.h"
#include "stream/Npy.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

using namespace penumbra;
using namespace penumbra::test;

TEST_CASE("no budget means one tile and a tight budget means more tiles", "[memory]") {
    MemoryDemand d;
    d.receivers = 1'000'000, d.scanBytes = 16'000'000, d.groups = 4, d.umbraWords = 1;
    MemoryPlan unlimited = planMemory(d, 0);
    CHECK(unlimited.tiles == 1);
    const uint64_t oneTileBudget = unlimited.residentBytes + d.receivers * unlimited.perReceiverBytes;
    CHECK(planMemory(d, oneTileBudget).tiles == 1);
    MemoryPlan tight = planMemory(d, unlimited.residentBytes + d.receivers * unlimited.perReceiverBytes / 4);
    CHECK(tight.tiles >= 4);
    CHECK(tight.tiles <= 5);
    // Every tile fits: resident + tile receivers x per-receiver bytes <= budget.
    CHECK(tight.residentBytes + (d.receivers + tight.tiles - 1) / tight.tiles * tight.perReceiverBytes <= tight.budget);
}

TEST_CASE("a budget below one smallest tile names the smallest budget that works", "[memory]") {
    MemoryDemand d;
    d.receivers = 2'000'000, d.scanBytes = 32'000'000, d.groups = 16, d.umbraWords = 1;
    MemoryPlan p = planMemory(d, 0);
    std::string message;
    try {
        planMemory(d, 1 << 20);
    } catch (const InputError& e) {
        message = e.what();
    }
    CHECK_THAT(message, Catch::StartsWith("--memory-budget 1.00 MiB is too small") && Catch::Contains("at least " + budgetText(p.minimumBudget) + " is needed"));
    CHECK(planMemory(d, p.minimumBudget).tiles >= 1);
}

TEST_CASE("a tiled bake under --memory-budget is bit-identical to an untiled one", "[memory][cli]") {
    ScratchDir dir("tiles");
    std::ofstream(dir / "scene.json") << R"({
      "geometry": [{"type": "grid", "cells": 6, "levels": 2, "size": 2, "floor_size": 5}],
      "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 64, "sample_sets": 4}],
      "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0.5,0], "width": 400, "height": 300},
      "output": "out/a.exr"})";
    RunResult whole = runPenumbra("bake " + (dir / "scene.json") + " -q --dump " + (dir / "whole") + " --stats " + (dir / "whole.json"));
    REQUIRE(whole.exitCode == 0);
    auto stats = nlohmann::json::parse(slurp(dir / "whole.json"));
    const uint64_t receivers = stats["receivers"];
    REQUIRE(receivers > 3 * kMinimumTileReceivers);
    // The smallest budget that works cuts the receivers into the smallest tiles the plan allows.
    const uint64_t budget = stats["memory_plan"]["minimum_budget_bytes"];

    RunResult tiled = runPenumbra("bake " + (dir / "scene.json") + " -q -o " + (dir / "b.exr") + " --dump " + (dir / "tiled") +
                                  " --stats " + (dir / "tiled.json") + " --memory-budget " + std::to_string(budget));
    INFO(tiled.err);
    REQUIRE(tiled.exitCode == 0);
    auto tiledStats = nlohmann::json::parse(slurp(dir / "tiled.json"));
    const int tiles = tiledStats["memory_plan"]["tiles"];
    CHECK(tiles >= 2);
    CHECK(tiledStats["table2"]["peak_hierarchy_memory_bytes"].get<uint64_t>() <
          stats["table2"]["peak_hierarchy_memory_bytes"].get<uint64_t>() * 3 / (2 * tiles));
    // The plan is honest: the tiled bake's peak RSS stays within the budget it was given.
    CHECK(tiledStats["counters"]["peak_rss_bytes"].get<uint64_t>() <= budget);
    CHECK(readNpy(dir / "tiled/masks.npy").data == readNpy(dir / "whole/masks.npy").data);
    CHECK(slurp(dir / "b.exr") == slurp(dir / "out/a.exr"));

    RunResult tooSmall = runPenumbra("bake " + (dir / "scene.json") + " -q --memory-budget 1M");
    CHECK(tooSmall.exitCode == 1);
    CHECK_THAT(tooSmall.err, Catch::Contains("--memory-budget 1.00 MiB is too small") && Catch::Contains("at least"));
    CHECK(lineCount(tooSmall.err) == 1);
}
