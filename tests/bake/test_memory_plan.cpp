// The memory plan: tiles chosen to fit --memory-budget, and a clear error naming the smallest
// budget that would work.

#include "CliRunner.h"

#include "bake/MemoryPlan.h"
#include "stream/util/Error.h"
#include "stream/util/Memory.h"
#include "stream/util/Npy.h"

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
    CHECK_THAT(message, Catch::StartsWith("--memory-budget 1 MiB is too small") && Catch::Contains("at least " + budgetText(p.minimumBudget) + " is needed"));
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
    CHECK_THAT(tooSmall.err, Catch::Contains("--memory-budget 1 MiB is too small") && Catch::Contains("at least"));
    CHECK(lineCount(tooSmall.err) == 1);
}

TEST_CASE("a refinement's check covers its cast and outputs after it, the tiles staying those cast so far", "[memory]") {
    MemoryDemand d;
    d.receivers = 500'000, d.scanBytes = 8'000'000, d.groups = 4, d.umbraWords = 1, d.outputBytes = 4'000'000;
    d.kindBytes = 30'000'000;  // the refinement's rasterizer
    const MemoryPlan pass = planMemory(d, 0);
    d.refinement = {2'000'000, 1'000'000, 12'000'000};
    const MemoryPlan both = planMemory(d, 0);
    CHECK(both.residentBytes == pass.residentBytes);
    CHECK(both.perReceiverBytes == pass.perReceiverBytes);
    MemoryDemand after = d;
    after.refinement = {};
    after.receivers += 2'000'000, after.kindBytes = 1'000'000, after.outputBytes = 12'000'000;
    CHECK(both.minimumBudget == std::max(pass.minimumBudget, planMemory(after, 0).minimumBudget));
    CHECK(both.minimumBudget > pass.minimumBudget);
    std::string message;
    try {
        planMemory(d, pass.minimumBudget);
    } catch (const InputError& e) {
        message = e.what();
    }
    CHECK_THAT(message, Catch::Contains("at least " + budgetText(both.minimumBudget) + " is needed") &&
                            Catch::Contains("antialiasing pass's up to 2000000 more receivers"));
    MemoryDemand passOnly = d;
    passOnly.refinement = {};
    CHECK(planMemory(d, both.minimumBudget).tiles == planMemory(passOnly, both.minimumBudget).tiles);
}

TEST_CASE("an antialiased bake too large for its budget fails once, before its antialiasing pass, naming a budget that works",
          "[memory][cli]") {
    ScratchDir dir("aa-budget");
    std::ofstream(dir / "scene.json") << R"({
      "geometry": [{"type": "grid", "cells": 6, "levels": 2, "size": 2, "floor_size": 5}],
      "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 64, "sample_sets": 4}],
      "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0.5,0], "width": 400, "height": 300,
                    "antialias": {"threshold": 0.05, "samples": 16}},
      "output": "out/a.exr"})";
    RunResult whole = runPenumbra("bake " + (dir / "scene.json") + " -q --threads 2 --stats " + (dir / "whole.json"));
    REQUIRE(whole.exitCode == 0);
    const auto stats = nlohmann::json::parse(slurp(dir / "whole.json"));
    REQUIRE(stats["antialias"]["added_receivers"].get<uint64_t>() > 0);
    // The minimum the stats name covers every stage, the antialiasing pass's included, and the
    // bake under it stays within it.
    const uint64_t minimum = stats["memory_plan"]["minimum_budget_bytes"];
    RunResult atMinimum = runPenumbra("bake " + (dir / "scene.json") + " -q --threads 2 --memory-budget " + std::to_string(minimum) +
                                      " -o " + (dir / "m.exr") + " --stats " + (dir / "m.json"));
    INFO(atMinimum.err);
    REQUIRE(atMinimum.exitCode == 0);
    CHECK(slurp(dir / "m.exr") == slurp(dir / "out/a.exr"));
    CHECK(nlohmann::json::parse(slurp(dir / "m.json"))["counters"]["peak_rss_bytes"].get<uint64_t>() <= minimum);

    // Below it, at several budgets: one error line before the antialiasing pass, no output, and
    // the budget it names works.
    for (const uint64_t less : {1ull << 20, 4ull << 20, 12ull << 20}) {
        RunResult tooSmall = runPenumbra("bake " + (dir / "scene.json") + " --threads 2 --memory-budget " + std::to_string(minimum - less) +
                                         " -o " + (dir / "small.exr"));
        INFO(tooSmall.err);
        CHECK(tooSmall.exitCode == 1);
        CHECK_THAT(tooSmall.err, Catch::Contains("is too small") && !Catch::Contains("[antialias]"));
        CHECK_FALSE(std::filesystem::exists(dir / "small.exr"));
        const size_t at = tooSmall.err.find("at least ");
        REQUIRE(at != std::string::npos);
        const std::string named = tooSmall.err.substr(at + 9, tooSmall.err.find(' ', at + 9) - at - 9);
        RunResult fits = runPenumbra("bake " + (dir / "scene.json") + " -q --threads 2 --memory-budget " + named + " -o " + (dir / "b.exr"));
        INFO(named << ": " << fits.err);
        CHECK(fits.exitCode == 0);
        CHECK(slurp(dir / "b.exr") == slurp(dir / "out/a.exr"));
    }
}

TEST_CASE("a refused budget never reads as the amount named as enough", "[memory]") {
    // 102.8 MiB read "103 MiB is too small ...; at least 103M is needed".
    CHECK(refusedBudgetText(107789912) == "102.7 MiB");
    CHECK(budgetText(107789912) == "103M");
    CHECK(refusedBudgetText(103ull << 20) == "103 MiB");
    CHECK(refusedBudgetText((103ull << 20) - 1) == "102.9 MiB");
    CHECK(refusedBudgetText(1024) == "1.00 KiB");
}

TEST_CASE("many sample sets are counted before they are generated", "[memory][cli]") {
    // 65,536 samples x 64 sets: generating them takes about 420 MB (positions, the bound's copies
    // of every set's points, its hull). Under 200M or an address space of 300 MB the refusal came
    // only after that: 424 MB of RSS under a 200M budget, and "out of memory" naming 175 MiB
    // under the cap. Now both are refused before, naming what the bake needs.
    ScratchDir dir("many-sets");
    std::ofstream(dir / "p.csv") << "0,0,0,0,1,0\n0.3,0,0.2,0,1,0\n";
    std::ofstream(dir / "scene.json")
        << R"({"geometry": [], "lights": [{"type": "rect", "center": [0, 1, 0], "u": [1, 0, 0], "v": [0, 0, 1],
              "samples": 65536, "sample_sets": 64}], "receivers": {"type": "points", "path": "p.csv"}, "output": "v.npy"})";
    for (const std::string& limit : {std::string("--memory-budget 200M"), std::string("")}) {
        RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q --threads 1 " + limit, limit.empty() ? "prlimit --as=300000000" : "");
        INFO(r.err);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.err, Catch::Contains("is too small for the passes before the receivers are counted") && !Catch::Contains("out of memory"));
        const size_t at = r.err.find("at least ");
        REQUIRE(at != std::string::npos);
        CHECK(parseByteSize(r.err.substr(at + 9, r.err.find(' ', at + 9) - at - 9), "named") > (uint64_t(600) << 20));
        CHECK_FALSE(std::filesystem::exists(dir / "v.npy"));
    }
}
