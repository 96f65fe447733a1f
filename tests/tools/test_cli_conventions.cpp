// Command-line conventions: --version, usage errors exit 2, an unknown command is named with
// the commands there are.

#include "CliRunner.h"

#include <catch2/catch.hpp>

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

    for (const char* args : {"", "bake", "bake scene.json --no-such-option", "bake scene.json --threads many", "info"}) {
        RunResult usage = runPenumbra(args);
        INFO(args << ": " << usage.err);
        CHECK(usage.exitCode == 2);
        CHECK(!usage.err.empty());
    }
    CHECK(runPenumbra("--help").exitCode == 0);
    CHECK(runPenumbra("bake --help").exitCode == 0);
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
