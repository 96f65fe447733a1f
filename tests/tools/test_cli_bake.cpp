// The `penumbra bake` and `compare` commands end to end: outputs, dump format, stats, and clean
// one-line errors for bad input.

#include "CliRunner.h"

#include "bake/output/ImageWriters.h"
#include "stream/util/Npy.h"

#include "GltfValidator.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <fstream>
#include <sstream>

using namespace penumbra;
using namespace penumbra::test;

namespace {

const char* kSmallScene = R"({
  "geometry": [{"type": "grid", "cells": 4, "levels": 2, "size": 2, "floor_size": 5}],
  "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 64, "sample_sets": 4}],
  "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0.5,0], "width": 40, "height": 30},
  "output": "out/small.exr"})";

void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

}  // namespace

TEST_CASE("bake writes the EXR, PNG, dump and stats, and hpc matches reference via compare", "[cli]") {
    ScratchDir dir("bake");
    write(dir / "scene.json", kSmallScene);
    RunResult hpc = runPenumbra("bake " + (dir / "scene.json") + " --quiet --dump " + (dir / "hpc") + " --stats " + (dir / "stats.json"));
    INFO(hpc.err);
    REQUIRE(hpc.exitCode == 0);
    CHECK(hpc.err.empty());  // --quiet

    ExrImage img = readExr(dir / "out/small.exr");
    CHECK(img.width == 40);
    CHECK(img.height == 30);
    REQUIRE(img.channels.count("visibility.V"));
    float lo = 1, hi = 0;
    for (float v : img.channels["visibility.V"]) lo = std::min(lo, v), hi = std::max(hi, v);
    CHECK(lo < 0.2f);   // something is in shadow
    CHECK(hi == 1.0f);  // something is fully lit
    CHECK(std::filesystem::file_size(dir / "out/small.png") > 100);

    NpyArray rec = readNpy(dir / "hpc/receivers.npy"), smp = readNpy(dir / "hpc/samples.npy"), msk = readNpy(dir / "hpc/masks.npy");
    CHECK(rec.dtype == "<f4");
    REQUIRE(rec.shape.size() == 2);
    CHECK(rec.shape[1] == 7);
    CHECK(smp.shape == std::vector<uint64_t>{4, 64, 4});
    CHECK(msk.dtype == "<u8");
    CHECK(msk.shape == std::vector<uint64_t>{rec.shape[0], 1});

    nlohmann::json stats = nlohmann::json::parse(slurp(dir / "stats.json"));
    for (const char* key : {"sort_time_s", "hierarchy_build_time_s", "hierarchy_build_wall_s", "penumbra_cast_time_s", "samples_memory_bytes",
                            "peak_hierarchy_memory_bytes", "peak_mask_memory_bytes", "total_time_s"})
        CHECK(stats["table2"].contains(key));
    CHECK(stats["counters"]["triangles_read"].get<uint64_t>() == 2 + 2 * 25 * 12);
    CHECK(stats["counters"]["peak_rss_bytes"].get<uint64_t>() > 1000000);
    CHECK(stats["table2"]["peak_hierarchy_memory_bytes"].get<uint64_t>() > 0);
    CHECK(stats["counters"]["table_decided_relations"].get<uint64_t>() > 0);  // sample table on by default
    CHECK(stats["counters"]["closed_back_faces_skipped"].get<uint64_t>() > 0);  // the bars' undersides

    RunResult ref = runPenumbra("bake " + (dir / "scene.json") + " -q --method reference -o " + (dir / "ref.exr") + " --dump " + (dir / "ref"));
    REQUIRE(ref.exitCode == 0);
    RunResult cmp = runPenumbra("compare " + (dir / "hpc") + " " + (dir / "ref"));
    INFO(cmp.out);
    CHECK(cmp.exitCode == 0);
    CHECK_THAT(cmp.out, Catch::Contains("only_a 0") && Catch::Contains("only_b 0"));
    // Without --scene a mismatch is still listed and written, with no verdict (the CSV held only
    // its header): receiver 0's sample 0 flipped in a copy of the dump.
    std::filesystem::copy(dir.path / "ref", dir.path / "flip");
    std::string masks = slurp(dir / "flip/masks.npy");
    masks[10 + (uint8_t(masks[8]) | uint8_t(masks[9]) << 8)] ^= 1;
    std::ofstream(dir / "flip/masks.npy", std::ios::binary) << masks;
    RunResult flipped = runPenumbra("compare " + (dir / "ref") + " " + (dir / "flip") + " --list 5 --mismatches " + (dir / "mm.csv"));
    INFO(flipped.out << flipped.err);
    CHECK(flipped.exitCode == 3);
    CHECK_THAT(flipped.out, Catch::Contains("mismatch receiver 0 sample 0 (set ") && Catch::Contains("(give --scene for a verdict)"));
    CHECK(slurp(dir / "mm.csv") ==
          "receiver,sample,blocked_in,rule_blocks,tie,quantity,triangle,edge,value,threshold,tolerance\n0,0," +
              std::string((uint8_t(masks[10 + (uint8_t(masks[8]) | uint8_t(masks[9]) << 8)]) & 1) ? "B" : "A") + ",,,,,,,,\n");

    // Same result on one thread and with every optimization off.
    RunResult one = runPenumbra("bake " + (dir / "scene.json") + " -q --threads 1 --disable all -o " + (dir / "one.exr") + " --dump " + (dir / "one"));
    REQUIRE(one.exitCode == 0);
    CHECK(readNpy(dir / "one/masks.npy").data == msk.data);
    CHECK(readExr(dir / "one.exr").channels["visibility.V"] == img.channels["visibility.V"]);
    RunResult noTable = runPenumbra("bake " + (dir / "scene.json") + " -q --sample-table off -o " + (dir / "nt.exr") + " --dump " + (dir / "nt"));
    REQUIRE(noTable.exitCode == 0);
    CHECK(readNpy(dir / "nt/masks.npy").data == msk.data);
    RunResult allFaces = runPenumbra("bake " + (dir / "scene.json") + " -q --closed-casters off -o " + (dir / "af.exr") + " --dump " + (dir / "af"));
    REQUIRE(allFaces.exitCode == 0);
    CHECK(readNpy(dir / "af/masks.npy").data == msk.data);
}

TEST_CASE("bad input gives one clean line and a non-zero exit", "[cli]") {
    ScratchDir dir("bad");
    write(dir / "broken.json", "{ \"geometry\": [ ");
    requireCleanError(runPenumbra("bake " + (dir / "broken.json")), "broken.json: invalid JSON");

    requireCleanError(runPenumbra("bake " + (dir / "nonexistent.json")), "nonexistent.json");

    nlohmann::json s = nlohmann::json::parse(kSmallScene);
    s["lights"][0]["v"] = {0, 0, 0};
    write(dir / "zero.json", s.dump());
    requireCleanError(runPenumbra("bake " + (dir / "zero.json")), "lights[0]: zero-area light");

    write(dir / "nan.obj", "v 0 0 0\nv 1 0 0\nv 0 nan 1\nf 1 2 3\n");
    s = nlohmann::json::parse(kSmallScene);
    s["geometry"] = {{{"type", "obj"}, {"path", "nan.obj"}}};
    write(dir / "nan.json", s.dump());
    requireCleanError(runPenumbra("bake " + (dir / "nan.json")), "nan.obj");

    s["geometry"] = {{{"type", "obj"}, {"path", "missing.obj"}}};
    write(dir / "missing.json", s.dump());
    requireCleanError(runPenumbra("bake " + (dir / "missing.json")), "missing.obj");

    write(dir / "ok.json", kSmallScene);
    requireCleanError(runPenumbra("bake " + (dir / "ok.json") + " --method magic"), "--method");
    write(dir / "afile", "x");
    requireCleanError(runPenumbra("bake " + (dir / "ok.json") + " -q -o " + (dir / "afile") + "/sub/out.exr"), "afile");
    // make-example writes a .glb: GLB bytes under another extension are refused, not written.
    requireCleanError(runPenumbra("make-example gltf-tree -o " + (dir / "tree.obj")), "tree.obj: make-example gltf-tree writes a binary glTF");
    CHECK_FALSE(std::filesystem::exists(dir / "tree.obj"));
    REQUIRE(runPenumbra("make-example gltf-tree -o " + (dir / "tree.glb")).exitCode == 0);
    CHECK(runPenumbra("info -q " + (dir / "tree.glb")).exitCode == 0);
    CHECK_FALSE(hasTempFiles(dir.path));
    // What the command writes, and the checked-in example it wrote (with another compiler the
    // last bits of the trunk's sines may differ), are valid glTF, POSITION bounds included.
    std::string validatorDir, log;
    if (!validatorAvailable(validatorDir)) {
        WARN("skipped: gltf-validator not installed under " << validatorDir << " (./setup.sh installs it)");
        return;
    }
    for (const std::string& file : {dir / "tree.glb", std::string(PENUMBRA_SOURCE_DIR) + "/examples/gltf-tree.glb"}) {
        const int code = validateGltf(file, validatorDir, log);
        INFO(file << "\n" << log);
        CHECK(code == 0);
    }
}

TEST_CASE("a full disk while writing outputs leaves no partial file", "[cli]") {
    ScratchDir dir("fsize");
    nlohmann::json s = nlohmann::json::parse(kSmallScene);
    s["receivers"]["width"] = 320, s["receivers"]["height"] = 240;
    write(dir / "scene.json", s.dump());
    RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q", "prlimit --fsize=20000");
    INFO(r.err);
    CHECK(r.exitCode == 1);
    CHECK(lineCount(r.err) == 1);
    CHECK_FALSE(std::filesystem::exists(dir / "out/small.exr"));
    CHECK_FALSE(hasTempFiles(dir.path));
}

namespace {
/// A 1 x 1 quad.obj at y = 1 under a small rect light, with point receivers from @p file.
nlohmann::json pointsScene(const char* file, int samples) {
    return {{"geometry", {{{"type", "obj"}, {"path", "quad.obj"}}}},
            {"lights", {{{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {0.5, 0, 0}}, {"v", {0, 0, 0.5}}, {"samples", samples}}}},
            {"receivers", {{"type", "points"}, {"path", file}}},
            {"output", "vis.npy"}};
}
}  // namespace

TEST_CASE("point receivers from .npy and .csv bake to a .npy of visible fractions", "[cli]") {
    ScratchDir dir("points");
    // Three receivers on the floor: in the umbra of a 1x1 quad at y=1, in its penumbra
    // (x in [0.583, 0.75] for this light), and far away (lit).
    std::vector<float> pts = {0, 0, 0, 0, 1, 0, 0.66f, 0, 0, 0, 1, 0, 5, 0, 5, 0, 1, 0};
    uint64_t shape[2] = {3, 6};
    writeNpy(dir / "pts.npy", "<f4", shape, pts.data(), pts.size() * sizeof(float));
    std::ofstream(dir / "pts.csv") << "px,py,pz,nx,ny,nz\n0,0,0,0,1,0\n0.66,0,0,0,1,0\n5,0,5,0,1,0\n";
    std::ofstream(dir / "quad.obj") << "v -0.5 1 -0.5\nv 0.5 1 -0.5\nv 0.5 1 0.5\nv -0.5 1 0.5\nf 1 2 3 4\n";
    for (const char* file : {"pts.npy", "pts.csv"}) {
        std::ofstream(dir / "scene.json") << pointsScene(file, 64).dump();
        RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q");
        INFO(file << ": " << r.err);
        REQUIRE(r.exitCode == 0);
        NpyArray vis = readNpy(dir / "vis.npy");
        REQUIRE(vis.shape == std::vector<uint64_t>{3});
        const float* v = reinterpret_cast<const float*>(vis.data.data());
        CHECK(v[0] == 0.0f);
        CHECK(v[1] > 0.0f);
        CHECK(v[1] < 1.0f);
        CHECK(v[2] == 1.0f);
    }
}

TEST_CASE("point receivers of the wrong shape are named by their shape, never by the memory they would take", "[cli]") {
    ScratchDir dir("points-shape");
    std::ofstream(dir / "quad.obj") << "v -0.5 1 -0.5\nv 0.5 1 -0.5\nv 0.5 1 0.5\nv -0.5 1 0.5\nf 1 2 3 4\n";
    // A valid empty array of 10^15 rows of nothing, and 4 rows of 3 columns: neither is N x 6.
    const uint64_t huge[2] = {1000000000000000ull, 0}, narrow[2] = {4, 3};
    const std::vector<float> twelve(12, 0.5f);
    writeNpy(dir / "huge.npy", "<f4", huge, nullptr, 0);
    writeNpy(dir / "narrow.npy", "<f4", narrow, twelve.data(), twelve.size() * sizeof(float));
    for (const char* file : {"huge.npy", "narrow.npy"}) {
        std::ofstream(dir / "scene.json") << pointsScene(file, 16).dump();
        const RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q");
        INFO(file << ": " << r.err);
        CHECK(r.exitCode == 1);
        CHECK(lineCount(r.err) == 1);
        CHECK(r.err.find(file) != std::string::npos);
        CHECK(r.err.find("N x 6") != std::string::npos);
        CHECK(r.err.find("memory") == std::string::npos);
        CHECK_FALSE(std::filesystem::exists(dir / "vis.npy"));
    }
}

TEST_CASE("bake: the cast's progress lines on a terminal rise monotonically and only the last says 100 %", "[cli][progress]") {
    // `script` (util-linux) gives the bake a terminal, so the line is redrawn every 0.25 s.
    if (runShell("command -v script >/dev/null 2>&1") != 0) {
        WARN("script (util-linux) is not installed: skipped");
        return;
    }
    ScratchDir dir("progress");
    write(dir / "scene.json", R"({
      "geometry": [{"type": "grid", "cells": 24, "levels": 3, "size": 4, "floor_size": 10}],
      "lights": [{"type": "rect", "center": [0,5,0], "u": [2,0,0], "v": [0,0,2], "samples": 256, "sample_sets": 4}],
      "receivers": {"type": "camera", "eye": [0,5,7], "target": [0,0.5,0], "width": 320, "height": 240},
      "output": "out/progress.exr"})");
    const std::string bake = std::string(PENUMBRA_BINARY) + " bake " + (dir / "scene.json") + " --threads 2 --stats " + (dir / "s.json");
    REQUIRE(runShell("script -qfec '" + bake + "' " + (dir / "tty.txt") + " >/dev/null 2>&1") == 0);
    std::string text = slurp(dir / "tty.txt");
    std::replace(text.begin(), text.end(), '\r', '\n');
    std::vector<std::string> cast, shade;
    std::istringstream lines(text);
    for (std::string line; std::getline(lines, line);) {
        if (line.rfind("[cast] ", 0) == 0) cast.push_back(line);
        if (line.rfind("[shade] ", 0) == 0) shade.push_back(line);
    }
    // The pass that shades every receiver after the cast is a phase of its own, after the cast's
    // closing line, counting the receivers (under a light of thousands of samples it can take
    // longer than the cast, which would otherwise sit at 99.9 % through it).
    REQUIRE(!shade.empty());
    const nlohmann::json stats = nlohmann::json::parse(slurp(dir / "s.json"));
    const std::string receivers = std::to_string(stats["receivers"].get<uint64_t>());
    CHECK_THAT(shade.back(), Catch::StartsWith("[shade] 100.0% (" + receivers + "/" + receivers + ") done in "));
    CHECK(text.find("[shade] ") > text.rfind("[cast] "));
    CHECK(stats["table2"]["shade_time_s"].get<double>() > 0);
    REQUIRE(!cast.empty());
    double last = 0;
    for (size_t i = 0; i < cast.size(); ++i) {
        INFO(cast[i]);
        const double percent = std::stod(cast[i].substr(7));
        CHECK(percent >= last);
        last = percent;
        if (i + 1 < cast.size()) CHECK(percent < 100.0);
    }
    CHECK_THAT(cast.back(), Catch::StartsWith("[cast] 100.0% (") && Catch::Contains(" done in "));
    // The counts of the closing line are equal: every triangle was cast by every tile.
    const std::string counts = cast.back().substr(cast.back().find('(') + 1);
    CHECK(counts.substr(0, counts.find('/')) == counts.substr(counts.find('/') + 1, counts.find(')') - counts.find('/') - 1));
}

TEST_CASE("a camera's write phase counts its rows, so it shows a share and an ETA", "[cli]") {
    // It showed only its elapsed time: 6-8 s of "[write] elapsed" on a 4000x3000 image.
    ScratchDir dir("write-progress");
    std::ofstream(dir / "scene.json") << R"({"geometry": [{"type": "grid", "levels": 1, "cells": 2, "size": 3, "floor_size": 8}],
        "lights": [{"type": "rect", "center": [0, 5, 0], "u": [1, 0, 0], "v": [0, 0, 1], "samples": 4}],
        "receivers": {"type": "camera", "eye": [0, 3, 4], "target": [0, 0, 0], "width": 64, "height": 150},
        "output": "out/x.exr"})";
    const RunResult r = runPenumbra("bake " + (dir / "scene.json") + " --threads 1");
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    CHECK(r.err.find("[write] 100.0% (150/150) done in") != std::string::npos);
}
