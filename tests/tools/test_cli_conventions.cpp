// Command-line conventions: --version, usage errors exit 2, an unknown command is named with
// the commands there are.

#include "CliRunner.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

using namespace penumbra::test;

TEST_CASE("cli: --version, usage errors exit 2 and an unknown command lists the commands", "[cli]") {
    RunResult version = runPenumbra("--version");
    CHECK(version.exitCode == 0);
    CHECK(version.out == "penumbra " PENUMBRA_VERSION_TEXT "\n");

    RunResult unknown = runPenumbra("frobnicate");
    INFO(unknown.err);
    CHECK(unknown.exitCode == 2);
    CHECK(lineCount(unknown.err) == 1);
    CHECK_THAT(unknown.err, Catch::Contains("penumbra: error: unknown command 'frobnicate'") && Catch::Contains("bake") &&
                                Catch::Contains("convert") && Catch::Contains("vdb-slice"));

    // A malformed value is a usage error, whatever the option (a refused value of the right form,
    // --memory-budget 0 or --shard 5/3, is an input error, exit 1).
    for (const char* args : {"", "bake", "bake scene.json --no-such-option", "bake scene.json --threads many", "info",
                             "bake scene.json --memory-budget 12Q", "bake scene.json --memory-budget x", "bake scene.json --shard x/y",
                             "slurm scene.json --shards 2 --memory-budget lots"}) {
        RunResult usage = runPenumbra(args);
        INFO(args << ": " << usage.err);
        CHECK(usage.exitCode == 2);
        CHECK(lineCount(usage.err) == 1);  // one line, as every other error
        CHECK_THAT(usage.err, Catch::StartsWith("penumbra: error: ") && Catch::Contains("--help)"));
    }
    RunResult range = runPenumbra("combine shards --range x");
    CHECK(range.exitCode == 2);
    CHECK_THAT(range.err, Catch::Contains("'x' is not A-B"));
    // A value of the right form out of range is an input error naming the option, NaN included.
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/examples/grids.json";
    for (const std::string& args : {"bake " + scene + " --method penumbra-map --penumbra-map-taps 9",
                                    "bake " + scene + " --method penumbra-map --penumbra-map-resolution 8",
                                    "bake " + scene + " --method penumbra-map --penumbra-map-bias -1",
                                    "bake " + scene + " --method penumbra-map --penumbra-map-bias nan",
                                    "slurm " + scene + " --shards 0 --dry-run", "slurm " + scene + " --shards 2 --threads 0 --dry-run"}) {
        RunResult refused = runPenumbra(args);
        INFO(args << ": " << refused.err);
        CHECK(refused.exitCode == 1);
        CHECK(lineCount(refused.err) == 1);
        CHECK_THAT(refused.err, Catch::StartsWith("penumbra: error: --") && Catch::Contains(": must be in "));
    }
    // No command, or an option before one: named as such, with the commands listed.
    CHECK_THAT(runPenumbra("").err, Catch::StartsWith("penumbra: error: no command given (commands: bake,"));
    RunResult option = runPenumbra("--bogus");
    CHECK(option.exitCode == 2);
    CHECK_THAT(option.err, Catch::StartsWith("penumbra: error: unknown option '--bogus' before a command (commands: bake,"));
    // A command of commands names what it takes, and a usage error under one of its commands
    // points at that command's help.
    RunResult bench = runPenumbra("bench nope");
    CHECK(bench.exitCode == 2);
    CHECK(bench.err == "penumbra: error: unknown bench 'nope' (known: generators, table2, methods; see penumbra bench --help)\n");
    CHECK(runPenumbra("bench").err == "penumbra: error: bench needs one of: generators, table2, methods (see penumbra bench --help)\n");
    CHECK_THAT(runPenumbra("bench table2 --threads x").err, Catch::EndsWith("(see penumbra bench table2 --help)\n"));
    RunResult conversion = runPenumbra("bake scene.json --threads many");
    CHECK(conversion.err == "penumbra: error: could not convert: --threads = many (see penumbra bake --help)\n");
    CHECK(runPenumbra("--help").exitCode == 0);
    CHECK(runPenumbra("bake --help").exitCode == 0);
    // merge runs as bake --merge, but its help names merge, with the bake's options.
    RunResult merge = runPenumbra("merge --help");
    CHECK(merge.exitCode == 0);
    CHECK_THAT(merge.out, Catch::StartsWith("merge shard files into a bake's outputs") &&
                              Catch::Contains("Usage: penumbra merge [OPTIONS] scene") && Catch::Contains("--shard-dir"));
    CHECK_THAT(merge.out, !Catch::Contains("bake [OPTIONS]"));
}

TEST_CASE("cli: -o names the format by its extension and a bake refuses one its receivers cannot write", "[cli]") {
    ScratchDir dir("cli-ext");
    std::ofstream(dir / "scene.json") << R"({
  "geometry": [{"type": "grid", "cells": 2, "levels": 1, "size": 2, "floor_size": 5}],
  "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 16}],
  "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0.5,0], "width": 8, "height": 6},
  "output": "out/small.exr"})";
    for (const char* name : {"x.tiff", "x.png", "x.npy", "x"}) {
        RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q -o " + (dir / name));
        requireCleanError(r, "--output: \"" + (dir / name) + "\": camera receivers write .exr files");
        CHECK(!std::filesystem::exists(dir / name));
        CHECK(!std::filesystem::exists(dir / "x.exr"));
    }
    RunResult upper = runPenumbra("bake " + (dir / "scene.json") + " -q -o " + (dir / "X.EXR"));
    INFO(upper.err);
    CHECK(upper.exitCode == 0);
    CHECK(std::filesystem::exists(dir / "X.EXR"));
    std::ofstream(dir / "tiff.json") << R"({
  "geometry": [{"type": "grid", "cells": 2, "levels": 1, "size": 2, "floor_size": 5}],
  "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 16}],
  "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0.5,0], "width": 8, "height": 6},
  "output": "out/small.tiff"})";
    requireCleanError(runPenumbra("bake " + (dir / "tiff.json") + " -q"), "tiff.json: output: \"");
}

namespace {

/// A small camera scene in @p dir with @p light as its one light and @p extra keys merged in.
std::string smallScene(const ScratchDir& dir, const std::string& light, const std::string& receivers = "") {
    std::ofstream(dir / "scene.json") << R"({
  "geometry": [{"type": "grid", "cells": 2, "levels": 1, "size": 2, "floor_size": 5}],
  "lights": [)" + light + R"(],
  "receivers": )" + (receivers.empty() ? R"({"type": "camera", "eye": [0,4,5], "target": [0,0.5,0], "width": 8, "height": 6})" : receivers) + R"(,
  "output": "out/small.exr"})";
    return dir / "scene.json";
}

const char* kDownLight = R"({"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 16})";

}  // namespace

TEST_CASE("cli: the summary line names every file the bake wrote", "[cli]") {
    ScratchDir dir("cli-summary");
    const std::string scene = smallScene(dir, kDownLight);
    RunResult r = runPenumbra("bake " + scene + " --stats " + (dir / "s.json"));
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.err, Catch::Contains("-> " + (dir / "out/small.exr") + ", " + (dir / "out/small.png") + ", " + (dir / "s.json")));
    const nlohmann::json stats = nlohmann::json::parse(slurp(dir / "s.json"));
    // "lists them all": the stats file too (it was left out).
    CHECK(stats["outputs_written"] == nlohmann::json::array({dir / "out/small.exr", dir / "out/small.png", dir / "s.json"}));
}

TEST_CASE("cli: -o into a missing folder is an error while the scene's own output folder is made", "[cli]") {
    ScratchDir dir("cli-folder");
    const std::string scene = smallScene(dir, kDownLight);
    RunResult r = runPenumbra("bake " + scene + " -q -o " + (dir / "missing/deeper/x.exr"));
    INFO(r.err);
    CHECK(r.exitCode == 1);
    CHECK(lineCount(r.err) == 1);
    CHECK_THAT(r.err, Catch::StartsWith("penumbra: error: --output: ") && Catch::Contains((dir / "missing/deeper")) &&
                          Catch::Contains("does not exist"));
    CHECK(!std::filesystem::exists(dir / "missing"));
    RunResult own = runPenumbra("bake " + scene + " -q");  // out/ beside the scene is created
    CHECK(own.exitCode == 0);
    CHECK(std::filesystem::exists(dir / "out/small.exr"));
}

TEST_CASE("cli: a light facing away from every receiver and a camera that sees nothing are warnings even with -q", "[cli]") {
    ScratchDir dir("cli-warnings");
    // u and v swapped: the light emits upwards, away from the floor and the grid.
    std::string scene = smallScene(dir, R"({"type": "rect", "center": [0,4,0], "u": [0,0,1], "v": [1,0,0], "samples": 16})");
    RunResult away = runPenumbra("bake " + scene + " -q --stats " + (dir / "s.json"));
    INFO(away.err);
    CHECK(away.exitCode == 0);
    CHECK(lineCount(away.err) == 1);
    CHECK_THAT(away.err, Catch::StartsWith("penumbra: warning: ") && Catch::Contains("lights[0]: faces away from every receiver") &&
                             Catch::Contains("swap \"u\" and \"v\""));
    CHECK(nlohmann::json::parse(slurp(dir / "s.json"))["warnings"].size() == 1);
    // A light facing the receivers warns of nothing.
    scene = smallScene(dir, kDownLight);
    RunResult fine = runPenumbra("bake " + scene + " -q");
    CHECK(fine.exitCode == 0);
    CHECK(fine.err.empty());
    // A camera looking away from everything.
    scene = smallScene(dir, kDownLight, R"({"type": "camera", "eye": [0,4,5], "target": [0,8,20], "width": 8, "height": 6})");
    RunResult nothing = runPenumbra("bake " + scene + " -q");
    INFO(nothing.err);
    CHECK(nothing.exitCode == 0);
    CHECK_THAT(nothing.err, Catch::Contains("penumbra: warning: " + scene + ": receivers: the camera sees no geometry"));
}

TEST_CASE("cli: a misspelt key is named with the known key it is closest to", "[cli][scene]") {
    ScratchDir dir("cli-typo");
    std::string scene = smallScene(dir, kDownLight, R"({"type": "camera", "eye": [0,4,5], "target": [0,0.5,0], "fov": 30})");
    RunResult fov = runPenumbra("bake " + scene + " -q");
    CHECK(fov.exitCode == 1);
    CHECK_THAT(fov.err, Catch::Contains("receivers.fov: unknown key; did you mean \"fov_deg\"?"));
    std::ofstream(dir / "typo.json") << R"({"geometry": [{"type": "grid"}],
      "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1]}],
      "recievers": {"type": "camera", "eye": [0,4,5], "target": [0,0,0]}})";
    RunResult top = runPenumbra("bake " + (dir / "typo.json") + " -q");
    CHECK(top.exitCode == 1);
    CHECK(lineCount(top.err) == 1);
    CHECK_THAT(top.err, Catch::Contains("receivers: missing required field; is \"recievers\" a misspelling of it?"));
    std::ofstream(dir / "far.json") << R"({"geometry": [{"type": "grid", "heigth": 2}],
      "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1]}],
      "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0,0]}})";
    CHECK_THAT(runPenumbra("bake " + (dir / "far.json") + " -q").err,
               Catch::Contains("geometry[0].heigth: unknown key; did you mean \"height\"?"));
}

TEST_CASE("cli: without an \"output\" the scene's receivers pick the format", "[cli]") {
    ScratchDir dir("cli-default-output");
    std::ofstream(dir / "v.json") << R"({"geometry": [{"type": "grid", "cells": 2, "levels": 1, "size": 2, "floor_size": 5}],
      "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 16}],
      "receivers": {"type": "volume", "voxel_size": 0.5, "box": [[-1, 0.1, -1], [1, 1, 1]]}})";
    RunResult r = runPenumbra("bake " + (dir / "v.json") + " -q");
    INFO(r.err);
    CHECK(r.exitCode == 0);
    CHECK(std::filesystem::exists(dir / "out/shadows.vdb"));
}
