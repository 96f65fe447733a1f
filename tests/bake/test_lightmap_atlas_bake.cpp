// The lightmap kind with generated UVs: meshes without usable UVs share one atlas, which bakes
// the same visibility as the reference caster, is byte-identical for any thread count, comes
// with a glTF whose TEXCOORD_1 lays the meshes out as the atlas (checked by the Khronos
// validator when installed), and meshes without normals get smooth crease-angle normals.

#include "AtlasChecks.h"
#include "CliRunner.h"
#include "LightmapTestMeshes.h"
#include "GltfValidator.h"

#include "bake/WorkPlan.h"
#include "bake/output/ImageWriters.h"
#include "receivers/LightmapReceivers.h"
#include "stream/IndexedMesh.h"
#include "stream/util/Npy.h"

#include <catch2/catch.hpp>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstring>
#include <fstream>
#include <numbers>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// A closed box without vt or vn: six quads, outward.
const char* kBoxObj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
                      "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 4 8 7 3\nf 1 5 8 4\nf 2 3 7 6\n";

/// A UV sphere of radius 1 as OBJ, positions only (no vt, no vn).
std::string sphereObj(int rings, int segments) {
    std::string obj = "v 0 1 0\n";
    for (int i = 1; i < rings; ++i)
        for (int j = 0; j < segments; ++j) {
            const double theta = std::numbers::pi * i / rings, phi = 2 * std::numbers::pi * j / segments;
            obj += fmt::format("v {} {} {}\n", std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
        }
    obj += "v 0 -1 0\n";
    auto at = [&](int i, int j) {
        if (i == 0) return 1;
        if (i == rings) return 2 + (rings - 1) * segments;
        return 2 + (i - 1) * segments + j % segments;
    };
    for (int i = 0; i < rings; ++i)
        for (int j = 0; j < segments; ++j) {
            if (i > 0) obj += fmt::format("f {} {} {}\n", at(i, j), at(i, j + 1), at(i + 1, j));
            if (i < rings - 1) obj += fmt::format("f {} {} {}\n", at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
        }
    return obj;
}

/// A floor quad (own UVs), a box lifted above it (no UVs) and a light above both.
std::string sceneJson(const std::string& receivers, const std::string& output = "out/lightmap.exr") {
    return R"({"geometry": [{"type": "obj", "path": "quad.obj", "transform": {"scale": 4, "translate": [-2, 0, 2]}},
                            {"type": "obj", "path": "box.obj", "transform": {"scale": 0.5, "translate": [-0.25, 0.6, -0.25]}}],
               "lights": [{"type": "rect", "center": [0, 3, 0], "u": [1, 0, 0], "v": [0, 0, 1], "samples": 64, "sample_sets": 4}],
               "receivers": )" + receivers + R"(, "output": ")" + output + "\"}";
}

RunResult bake(const ScratchDir& dir, const std::string& args) {
    RunResult r = runPenumbra("bake " + (dir / "scene.json") + " --quiet " + args);
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    return r;
}

}  // namespace

TEST_CASE("lightmap atlas: meshes without UVs bake into one atlas, meshes with UVs keep theirs", "[lightmap][atlas][cli]") {
    ScratchDir dir("atlas-bake");
    writeText(dir / "quad.obj", kQuadObj);
    writeText(dir / "box.obj", kBoxObj);
    writeText(dir / "scene.json", sceneJson(R"({"type": "lightmap", "meshes": [0, 1], "resolution": 64, "padding": 2})"));
    bake(dir, "--stats " + (dir / "stats.json"));
    const nlohmann::json stats = nlohmann::json::parse(slurp(dir / "stats.json"));
    std::vector<std::string> outputs = stats["outputs"].get<std::vector<std::string>>();
    std::sort(outputs.begin(), outputs.end());
    const std::vector<std::string> expected{dir / "out/lightmap-atlas.exr", dir / "out/lightmap-atlas.png",
                                            dir / "out/lightmap-quad.exr", dir / "out/lightmap-quad.png",
                                            dir / "out/lightmap-uv1.glb"};
    CHECK(outputs == expected);
    CHECK(dir.find("lightmap").size() == expected.size());  // and nothing else
    CHECK(stats["lightmap"]["atlas"]["width"] == 64);
    CHECK(stats["lightmap"]["atlas"]["charts"] == 6);  // a box: one chart per face

    ExrImage atlas = readExr(dir / "out/lightmap-atlas.exr");
    CHECK(atlas.width == 64);
    // The box's top is lit, its bottom faces the floor, away from the light.
    float lo = 1, hi = 0;
    for (size_t t = 0; t < atlas.channels["A"].size(); ++t)
        if (atlas.channels["A"][t] > 0) lo = std::min(lo, atlas.channels["visibility.V"][t]), hi = std::max(hi, atlas.channels["visibility.V"][t]);
    CHECK(hi == 1.0f);
    ExrImage quad = readExr(dir / "out/lightmap-quad.exr");
    float shadow = 1;
    for (float v : quad.channels["visibility.V"]) shadow = std::min(shadow, v);
    CHECK(shadow < 0.5f);  // the box shadows the floor

    // The glTF lays the box out as the atlas: read back, its UVs give a sound atlas.
    std::vector<IndexedMesh> meshes = loadIndexedMeshes(dir / "out/lightmap-uv1.glb", glm::mat4(1.f));
    REQUIRE(meshes.size() == 1);
    CHECK(meshes[0].name == "box");
    REQUIRE(meshes[0].uv1.size() == meshes[0].position.size());
    REQUIRE(meshes[0].normal.size() == meshes[0].position.size());
    for (const glm::vec3& p : meshes[0].position) {  // in world space: the scene transform applied
        CHECK(p.y >= 0.6f - 1e-6f);
        CHECK(p.y <= 1.1f + 1e-6f);
    }
    LightmapLayout layout = rasterizeLightmap(meshes[0], 64, 64);
    CHECK(layout.overlapping == 0);
    size_t covered = 0;
    for (float a : atlas.channels["A"]) covered += a > 0;
    CHECK(layout.texel.size() == covered);

    std::string validatorDir, log;
    if (!validatorAvailable(validatorDir)) {
        WARN("skipped: gltf-validator not installed under " << validatorDir << " (./setup.sh installs it)");
        return;
    }
    const int code = validateGltf(dir / "out/lightmap-uv1.glb", validatorDir, log);
    INFO(log);
    CHECK(code == 0);
}

TEST_CASE("lightmap atlas: the atlas bakes the reference's visibility, the same bytes for any thread count", "[lightmap][atlas][cli]") {
    ScratchDir dir("atlas-exact");
    writeText(dir / "quad.obj", kQuadObj);
    writeText(dir / "box.obj", kBoxObj);
    writeText(dir / "scene.json", sceneJson(R"({"type": "lightmap", "meshes": [0, 1], "uv": "generate", "texels_per_unit": 8, "padding": 1})"));
    for (const char* folder : {"one", "two", "ref"}) std::filesystem::create_directories(dir / folder);  // -o names an existing folder
    bake(dir, "--threads 1 -o " + (dir / "one/lightmap.exr"));
    bake(dir, "--threads 2 -o " + (dir / "two/lightmap.exr"));
    bake(dir, "--method reference -o " + (dir / "ref/lightmap.exr"));
    for (const char* file : {"lightmap-atlas.exr", "lightmap-uv1.glb", "lightmap-atlas.png"})
        CHECK(slurp(dir / (std::string("one/") + file)) == slurp(dir / (std::string("two/") + file)));
    ExrImage hpc = readExr(dir / "one/lightmap-atlas.exr"), reference = readExr(dir / "ref/lightmap-atlas.exr");
    CHECK(hpc.channels["visibility.V"] == reference.channels["visibility.V"]);
    CHECK(hpc.channels["A"] == reference.channels["A"]);
    CHECK(!std::filesystem::exists(dir / "one/lightmap-quad.exr"));  // "generate": the quad is in the atlas too
}

TEST_CASE("lightmap atlas: a sphere without normals bakes with smooth normals, faceted at crease 0", "[lightmap][atlas][cli]") {
    ScratchDir dir("atlas-normals");
    writeText(dir / "ball.obj", sphereObj(12, 24));
    auto receiverNormals = [&](double crease) {
        writeText(dir / "scene.json", fmt::format(R"({{"geometry": [{{"type": "obj", "path": "ball.obj"}}],
            "lights": [{{"type": "rect", "center": [0, 3, 0], "u": [1, 0, 0], "v": [0, 0, 1], "samples": 16, "sample_sets": 1}}],
            "receivers": {{"type": "lightmap", "meshes": [0], "resolution": 128, "padding": 1, "crease_angle_deg": {}}},
            "output": "out/ball.exr"}})", crease));
        std::filesystem::remove_all(dir / "dump");
        bake(dir, "--dump " + (dir / "dump"));
        NpyArray receivers = readNpy(dir / "dump/receivers.npy");
        std::vector<float> rows(receivers.shape[0] * 7);
        std::memcpy(rows.data(), receivers.data.data(), rows.size() * 4);
        double lowest = 1;  // the smallest cosine between a receiver's normal and the sphere's
        for (size_t r = 0; r < receivers.shape[0]; ++r) {
            const glm::dvec3 p(rows[7 * r], rows[7 * r + 1], rows[7 * r + 2]), n(rows[7 * r + 3], rows[7 * r + 4], rows[7 * r + 5]);
            lowest = std::min(lowest, glm::dot(glm::normalize(p), n));
        }
        return lowest;
    };
    const double smooth = receiverNormals(60), faceted = receiverNormals(0);
    INFO("smooth " << smooth << ", faceted " << faceted);
    CHECK(smooth > 0.9998);  // interpolated vertex normals: within about a degree of the true normal
    CHECK(faceted < 0.99);   // facets of 15 x 15 degrees: up to ~10 degrees off at their corners
}

TEST_CASE("lightmap atlas: charts that cannot fit are an error naming the key", "[lightmap][atlas][cli]") {
    ScratchDir dir("atlas-full");
    writeText(dir / "quad.obj", kQuadObj);
    writeText(dir / "box.obj", kBoxObj);
    writeText(dir / "scene.json", sceneJson(R"({"type": "lightmap", "meshes": [1], "resolution": 8, "padding": 4})"));
    RunResult r = runPenumbra("bake " + (dir / "scene.json") + " --quiet");
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.err, Catch::Contains("receivers") && Catch::Contains("do not fit a 8x8 atlas with padding 4"));
    CHECK(lineCount(r.err) == 1);
    CHECK(dir.find("lightmap").empty());
}

TEST_CASE("lightmap atlas: a texels_per_unit no atlas can hold is refused before the packing", "[lightmap][atlas][cli]") {
    // A 16384² atlas, which the density would be lowered to fill, needs about 52 GiB; on a machine
    // with less, the refusal came after minutes of packing. (On a larger machine the bake goes on.)
    if (machineMemoryBytes() >= (60ull << 30)) {
        WARN("not checked: this machine could hold a 16384x16384 lightmap");
        return;
    }
    ScratchDir dir("atlas-density");
    writeText(dir / "quad.obj", kQuadObj);
    writeText(dir / "box.obj", kBoxObj);
    writeText(dir / "scene.json", sceneJson(R"({"type": "lightmap", "meshes": [1], "texels_per_unit": 1e9})"));
    RunResult r = runPenumbra("bake " + (dir / "scene.json") + " --quiet");
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.err, Catch::Contains("receivers: a lightmap at texels_per_unit 1000000000") && Catch::Contains("needs at least"));
    CHECK(lineCount(r.err) == 1);
    CHECK(dir.find("lightmap").empty());
}

TEST_CASE("lightmap: an OBJ entry's parts pick the o/g groups that get lightmaps", "[lightmap][cli]") {
    ScratchDir dir("atlas-parts");
    writeText(dir / "quad.obj", kQuadObj);
    // Two groups: the box and a second, separate box above it.
    std::string two = "o lower\n" + std::string(kBoxObj) + "o upper\n";
    two += "v 0 2 0\nv 1 2 0\nv 1 3 0\nv 0 3 0\nv 0 2 1\nv 1 2 1\nv 1 3 1\nv 0 3 1\n"
           "f 9 12 11 10\nf 13 14 15 16\nf 9 10 14 13\nf 12 16 15 11\nf 9 13 16 12\nf 10 11 15 14\n";
    writeText(dir / "box.obj", two);
    std::string scene = sceneJson(R"({"type": "lightmap", "meshes": [1], "resolution": 64, "padding": 2})");
    const std::string entry = R"("path": "box.obj",)";
    scene.replace(scene.find(entry), entry.size(), entry + R"( "parts": ["upper"],)");
    writeText(dir / "scene.json", scene);
    bake(dir, "--stats " + (dir / "stats.json"));
    const nlohmann::json stats = nlohmann::json::parse(slurp(dir / "stats.json"));
    std::vector<IndexedMesh> meshes = loadIndexedMeshes(dir / "out/lightmap-uv1.glb", glm::mat4(1.f));
    REQUIRE(meshes.size() == 1);  // only the group the entry names
    CHECK(meshes[0].name == "upper");
    CHECK(stats["lightmap"]["atlas"]["charts"] == 6);
}

TEST_CASE("lightmap: the memory plan counts the texels, before the scan and under a budget", "[lightmap][memory][cli]") {
    // The example at 16384² (268M texels) cannot fit this machine: refused before any work, in
    // one line. At 1024² and the smallest budget the plan names, the peak RSS stays within it
    // (the layout was not counted, and a 4096² bake overran its budget by two thirds).
    ScratchDir dir("lightmap-plan");
    std::string scene = slurp(std::string(PENUMBRA_SOURCE_DIR) + "/examples/lightmap.json");
    const std::string size = "\"resolution\": 512";
    REQUIRE(scene.find(size) != std::string::npos);
    auto withResolution = [&](int r) {
        std::string s = scene;
        s.replace(s.find(size), size.size(), "\"resolution\": " + std::to_string(r));
        const std::string path = (std::filesystem::path(PENUMBRA_SOURCE_DIR) / "examples").string();
        for (const char* obj : {"room.obj", "room-blockers.obj"})
            std::filesystem::copy_file(path + "/" + obj, dir / obj, std::filesystem::copy_options::skip_existing);
        std::ofstream(dir / ("lm" + std::to_string(r) + ".json")) << s;
        return dir / ("lm" + std::to_string(r) + ".json");
    };
    RunResult huge = runPenumbra("bake " + withResolution(16384) + " -o " + dir / "huge.exr");
    requireCleanError(huge, "at least");
    CHECK(huge.err.find("[scan]") == std::string::npos);
    const std::string small = withResolution(1024);
    RunResult plan = runPenumbra("bake " + small + " -q -o " + dir / "a.exr --stats " + dir / "a.json");
    REQUIRE(plan.exitCode == 0);
    const uint64_t minimum = nlohmann::json::parse(slurp(dir / "a.json"))["memory_plan"]["minimum_budget_bytes"].get<uint64_t>();
    RunResult budgeted = runPenumbra("bake " + small + " -q -o " + dir / "b.exr --stats " + dir / "b.json --memory-budget " +
                                     std::to_string(minimum));
    INFO(budgeted.err);
    REQUIRE(budgeted.exitCode == 0);
    const nlohmann::json stats = nlohmann::json::parse(slurp(dir / "b.json"));
    CHECK(stats["counters"]["peak_rss_bytes"].get<uint64_t>() <= minimum);
    CHECK(slurp(dir / "a.exr") == slurp(dir / "b.exr"));
}

TEST_CASE("lightmap: the atlas's packing is a phase of its own on stderr, silent with -q", "[lightmap][atlas][cli]") {
    // beast.obj's 1,881 charts took 24 s to pack while the display still said "[scan] 99.9%".
    ScratchDir dir("lightmap-phase");
    const std::string examples = (std::filesystem::path(PENUMBRA_SOURCE_DIR) / "examples").string();
    for (const char* file : {"lightmap.json", "room.obj", "room-blockers.obj"})
        std::filesystem::copy_file(examples + "/" + file, dir / file);
    const RunResult shown = runPenumbra("bake " + dir / "lightmap.json" + " --threads 2 -o " + dir / "lm.exr");
    REQUIRE(shown.exitCode == 0);
    const size_t scan = shown.err.find("[scan] 100.0%"), atlas = shown.err.find("[atlas] 100.0%"),
                 bucket = shown.err.find("[bucket]");
    REQUIRE(scan != std::string::npos);
    REQUIRE(atlas != std::string::npos);
    CHECK(scan < atlas);
    CHECK(atlas < bucket);
    const RunResult quiet = runPenumbra("bake " + dir / "lightmap.json" + " --threads 2 -q -o " + dir / "lm.exr");
    REQUIRE(quiet.exitCode == 0);
    CHECK(quiet.err.empty());
}

TEST_CASE("lightmap: an obj entry's file is read as OBJ whatever its name, as the blocker stream reads it", "[lightmap][atlas][cli]") {
    // "The entry's type chooses the reader (an OBJ may be called mesh.txt)": the lightmap went by
    // the extension and refused it.
    ScratchDir dir("lightmap-obj-named-txt");
    writeText(dir / "quad.obj", kQuadObj);
    writeText(dir / "box.obj", kBoxObj);
    writeText(dir / "scene.json", sceneJson(R"({"type": "lightmap", "meshes": [1], "resolution": 64})"));
    bake(dir, "");
    const std::string expected = slurp(dir / "out/lightmap-atlas.exr");
    std::filesystem::rename(dir / "box.obj", dir / "box.txt");
    std::string scene = sceneJson(R"({"type": "lightmap", "meshes": [1], "resolution": 64})");
    scene.replace(scene.find("box.obj"), 7, "box.txt");
    writeText(dir / "scene.json", scene);
    std::filesystem::remove_all(dir / "out");
    bake(dir, "");
    CHECK(slurp(dir / "out/lightmap-atlas.exr").size() == expected.size());
    // A "file" entry goes by its extension, which names no mesh format here.
    const std::string entry = R"("type": "obj", "path": "box.txt")";
    scene.replace(scene.find(entry), entry.size(), R"("type": "file", "path": "box.txt")");
    writeText(dir / "scene.json", scene);
    RunResult r = runPenumbra("bake " + (dir / "scene.json") + " --quiet");
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.err, Catch::Contains("is not an obj, gltf or glb file"));
}
