// Camera EXRs as a compositor reads them: OpenImageIO's oiiotool (Debian openimageio-tools) sees
// R, G, B, A first, the passes as named layers, typed attributes and the camera matrices, and its
// statistics agree with what OpenEXR reads back.

#include "CliRunner.h"

#include "bake/output/ImageWriters.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <sstream>

using namespace penumbra;
using namespace penumbra::test;

namespace {

std::string smallScene(const std::string& exr) {
    return R"({
  "geometry": [{"type": "grid", "cells": 4, "levels": 2, "size": 2, "floor_size": 5}],
  "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 64, "sample_sets": 4}],
  "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0.5,0], "width": 40, "height": 30},
  )" + exr + R"("output": "out/small.exr"})";
}

/// The line of `oiiotool --stats` that starts with @p label, its numbers in channel order.
std::vector<double> statsRow(const std::string& stats, const std::string& label) {
    std::istringstream lines(stats);
    for (std::string line; std::getline(lines, line);) {
        const size_t at = line.find(label);
        if (at == std::string::npos) continue;
        std::istringstream numbers(line.substr(at + label.size()));
        std::vector<double> row;
        for (double x; numbers >> x;) row.push_back(x);
        return row;
    }
    return {};
}

std::string oiiotool(const ScratchDir& dir, const std::string& args) {
    const int code = runShell("oiiotool " + args + " >" + (dir / "oiio.txt") + " 2>&1");
    const std::string out = slurp(dir / "oiio.txt");
    INFO(out);
    REQUIRE(code == 0);
    return out;
}

}  // namespace

TEST_CASE("exr: oiiotool reads R, G, B, A first, named layers, typed attributes and agrees with OpenEXR", "[exr][cli]") {
    if (runShell("oiiotool --version >/dev/null 2>&1") != 0) {
        WARN("skipped: no oiiotool (Debian package openimageio-tools)");
        return;
    }
    ScratchDir dir("exr-clients");
    std::ofstream(dir / "scene.json") << smallScene("");
    RunResult bake = runPenumbra("bake " + (dir / "scene.json") + " -q");
    INFO(bake.err);
    REQUIRE(bake.exitCode == 0);
    const std::string path = dir / "out/small.exr";

    const std::string info = oiiotool(dir, "--info -v " + path);
    CHECK_THAT(info, Catch::Contains("channel list: R, G, B, A, depth.Z, normal.X, normal.Y, normal.Z, visibility.V"));
    CHECK_THAT(info, Catch::Contains("software: \"penumbra "));
    CHECK_THAT(info, Catch::Contains("worldToCamera: "));
    CHECK_THAT(info, Catch::Contains("worldToNDC: "));
    CHECK_THAT(info, Catch::Contains("penumbra:samples: 64"));  // an int, not the string "64"
    CHECK_THAT(info, Catch::Contains("penumbra:light0.center: 0, 4, 0"));  // a v3f

    // oiiotool's statistics against OpenEXR's reading, channel by channel in oiiotool's order.
    const std::string stats = oiiotool(dir, "--stats " + path);
    const std::vector<double> max = statsRow(stats, "Stats Max:"), inf = statsRow(stats, "Stats InfCount:");
    REQUIRE(max.size() == 9);
    REQUIRE(inf.size() == 9);
    ExrImage img = readExr(path);
    const char* order[] = {"R", "G", "B", "A", "depth.Z", "normal.X", "normal.Y", "normal.Z", "visibility.V"};
    size_t background = 0;
    for (float a : img.channels["A"]) background += a == 0.f;
    CHECK(background > 0);  // the camera sees the sky above the floor
    CHECK(inf[4] == double(background));  // depth.Z: +infinity exactly where nothing was hit
    for (size_t c = 0; c < 9; ++c) {
        float hi = -INFINITY;
        for (float x : img.channels[order[c]]) hi = std::max(hi, x);
        if (c == 4) continue;  // depth's maximum is the infinite background
        CHECK(max[c] == Approx(hi).margin(1e-6));
    }
    CHECK(max[0] > 0);  // R holds the irradiance: lit surfaces are bright
}

TEST_CASE("exr: half and tiled output as oiiotool sees it, depth kept float", "[exr][cli]") {
    if (runShell("oiiotool --version >/dev/null 2>&1") != 0) {
        WARN("skipped: no oiiotool (Debian package openimageio-tools)");
        return;
    }
    ScratchDir dir("exr-half");
    std::ofstream(dir / "scene.json") << smallScene(R"("exr": {"pixel_type": "half", "tile_size": 16},)");
    RunResult bake = runPenumbra("bake " + (dir / "scene.json") + " -q");
    INFO(bake.err);
    REQUIRE(bake.exitCode == 0);
    const std::string info = oiiotool(dir, "--info -v " + (dir / "out/small.exr"));
    CHECK_THAT(info, Catch::Contains("tile size: 16 x 16"));
    CHECK_THAT(info, Catch::Contains("depth.Z (float)"));
    CHECK_THAT(info, Catch::Contains("R (half)"));
    ExrImage img = readExr(dir / "out/small.exr");
    CHECK(img.channelTypes["R"] == "half");
    CHECK(img.channelTypes["depth.Z"] == "float");
    CHECK(img.tileWidth == 16);

    // The scene's compression reaches the file, and a lossless one keeps the pixels.
    std::ofstream(dir / "piz.json") << smallScene(R"("exr": {"pixel_type": "half", "tile_size": 16, "compression": "piz"},)");
    RunResult piz = runPenumbra("bake " + (dir / "piz.json") + " -q -o " + (dir / "piz.exr"));
    INFO(piz.err);
    REQUIRE(piz.exitCode == 0);
    CHECK_THAT(oiiotool(dir, "--info -v " + (dir / "piz.exr")), Catch::Contains("compression: \"piz\""));
    CHECK(readExr(dir / "piz.exr").channels == img.channels);
}

TEST_CASE("exr: rgb visibility puts V in R, G, B and the irradiance in its own layer, bad settings name the key", "[exr][cli]") {
    ScratchDir dir("exr-rgb");
    std::ofstream(dir / "scene.json") << smallScene(R"("exr": {"rgb": "visibility"},)");
    RunResult bake = runPenumbra("bake " + (dir / "scene.json") + " -q");
    INFO(bake.err);
    REQUIRE(bake.exitCode == 0);
    ExrImage img = readExr(dir / "out/small.exr");
    REQUIRE(img.channels.count("irradiance.R") == 1);
    CHECK(img.channels["R"] == img.channels["visibility.V"]);
    CHECK(img.channels["B"] == img.channels["visibility.V"]);
    CHECK(img.attribute<std::string>("penumbra:rgb") == "visibility");
    float e = 0;
    for (float x : img.channels["irradiance.R"]) e = std::max(e, x);
    CHECK(e > 0);

    for (const auto& [settings, key] : {std::pair{R"("exr": {"pixel_type": "double"},)", "exr.pixel_type"},
                                        {R"("exr": {"tile_size": 8},)", "exr.tile_size"},
                                        {R"("exr": {"rgb": "red"},)", "exr.rgb"},
                                        {R"("exr": {"tiles": 16},)", "exr.tiles"},
                                        {R"("exr": {"compression": "lzma"},)", "exr.compression"},
                                        {R"("exr": {"compression": "piz", "zip_level": 3},)", "exr.zip_level"},
                                        {R"("exr": {"zip_level": 12},)", "exr.zip_level"}}) {
        std::ofstream(dir / "bad.json") << smallScene(settings);
        RunResult bad = runPenumbra("bake " + (dir / "bad.json") + " -q -o " + (dir / "bad.exr"));
        requireCleanError(bad, key);
        CHECK(!std::filesystem::exists(dir / "bad.exr"));
    }
}
