// Scene files: strict parsing with errors that name the key.

#include "bake/Scene.h"
#include "procedural/Generators.h"
#include "stream/util/Error.h"

#include <catch2/catch.hpp>

#include <fcntl.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

using namespace penumbra;
using nlohmann::json;

namespace {

json minimal() {
    return json::parse(R"({
      "geometry": [{"type": "grid", "cells": 2, "levels": 1}],
      "lights": [{"type": "rect", "center": [0,5,0], "u": [1,0,0], "v": [0,0,1]}],
      "receivers": {"type": "camera", "eye": [0,3,8], "target": [0,0,0]},
      "output": "out/x.exr"})");
}

void requireError(const json& scene, const std::string& fragment) {
    INFO(scene.dump());
    REQUIRE_THROWS_AS(parseScene(scene, "dir/scene.json"), InputError);
    try {
        parseScene(scene, "dir/scene.json");
    } catch (const InputError& e) {
        std::string what = e.what();
        CHECK_THAT(what, Catch::StartsWith("dir/scene.json: ") && Catch::Contains(fragment));
        CHECK(what.find('\n') == std::string::npos);
    }
}

}  // namespace

TEST_CASE("a minimal scene parses with defaults and relative paths", "[scene]") {
    SceneDesc s = parseScene(minimal(), "dir/scene.json");
    CHECK(s.output == "dir/out/x.exr");
    REQUIRE(s.lights.size() == 1);
    CHECK(s.lights[0].samples == 256);
    CHECK(s.lights[0].sampleSets == 8);
    CHECK(s.receivers.at("type") == "camera");
    CHECK(s.options.umbraBits);
    CHECK(s.geometry[0].type == "grid");
    CHECK_FALSE(s.geometry[0].params.contains("type"));
}

TEST_CASE("a scene read through /dev/stdin or /proc/self/fd is relative to the file behind it", "[scene]") {
    // `penumbra bake /dev/stdin < scenes/a.json` resolved the scene's paths against /dev.
    const std::filesystem::path folder = std::filesystem::temp_directory_path() / ("penumbra-scene-fd-" + std::to_string(::getpid()));
    std::filesystem::create_directories(folder);
    std::ofstream(folder / "scene.json") << minimal().dump();
    const int fd = ::open((folder / "scene.json").c_str(), O_RDONLY);
    REQUIRE(fd >= 0);
    const SceneDesc s = parseScene(minimal(), "/proc/self/fd/" + std::to_string(fd));
    ::close(fd);
    const std::filesystem::path real = std::filesystem::canonical(folder);
    std::filesystem::remove_all(folder);
    CHECK(s.output == (real / "out/x.exr").string());
}

TEST_CASE("scene errors name the key", "[scene]") {
    json s = minimal();
    s["colour"] = 1;
    requireError(s, "colour: unknown key");
    s = minimal();
    s["lights"][0]["u"] = {1, 0};
    requireError(s, "lights[0].u: expected an array of 3 numbers");
    s = minimal();
    s["lights"][0].erase("v");
    requireError(s, "lights[0].v: missing required field");
    s = minimal();
    s["lights"][0]["samples"] = "many";
    requireError(s, "lights[0].samples");
    s = minimal();
    s["lights"][0]["type"] = "laser";
    requireError(s, "lights[0].type: unknown light type");
    s = minimal();
    s["lights"][0]["v"] = {2, 0, 0};
    requireError(s, "lights[0]: zero-area light");
    s = minimal();
    s["receivers"]["width"] = -3;
    requireError(s, "receivers.width");
    s = minimal();
    s["geometry"][0]["transform"] = {{"scal", 2}};
    requireError(s, "geometry[0].transform.scal: unknown key");
    s = minimal();
    s["bake"] = {{"rebuild_threshold", 3}};
    requireError(s, "bake.rebuild_threshold");
    s = minimal();
    s.erase("receivers");
    requireError(s, "receivers: missing required field");
}

TEST_CASE("a transform beyond float range is named by its key, and its vertices by the entry", "[scene]") {
    registerProceduralGenerators();
    json s = minimal();
    s["geometry"][0]["transform"] = {{"scale", 1e300}};
    requireError(s, "geometry[0].transform.scale: 1e+300 is beyond the float range of vertices");
    s["geometry"][0]["transform"] = {{"translate", {0, -1e39, 0}}};
    requireError(s, "geometry[0].transform.translate: -1e+39 is beyond the float range of vertices");
    // A float scale whose vertices overflow: named when they are read, with the entry.
    s["geometry"][0]["transform"] = {{"scale", 3e38}};
    const SceneDesc scene = parseScene(s, "dir/scene.json");
    TriangleSourcePtr source = openSceneGeometry(scene);
    std::vector<Triangle> chunk(1024);
    try {
        while (source->read(chunk) > 0) {}
        FAIL("no error");
    } catch (const InputError& e) {
        CHECK_THAT(std::string(e.what()), Catch::StartsWith("dir/scene.json: geometry[0].transform: moves a vertex of") &&
                                              Catch::Contains("beyond the float range"));
    }
}

TEST_CASE("a geometry file's path that is empty or names no file is an error naming its key", "[scene]") {
    registerFileSourceTypes();
    registerProceduralGenerators();
    const std::filesystem::path dir = std::filesystem::temp_directory_path() / "penumbra-scene-path";
    std::filesystem::create_directories(dir);
    json s = minimal();
    s["geometry"].push_back({{"type", "scatter"}, {"count", 2}, {"source", {{"type", "obj"}, {"path", ""}}}});
    for (const char* path : {"", "rock.obj"}) {
        s["geometry"][1]["source"]["path"] = path;
        const SceneDesc scene = parseScene(s, (dir / "scene.json").string());
        INFO(path);
        try {
            openSceneGeometry(scene);
            FAIL("no error");
        } catch (const InputError& e) {
            const std::string what = e.what();
            CHECK_THAT(what, Catch::StartsWith((dir / "scene.json").string() + ": geometry[1].source.path: ") &&
                                 Catch::Contains(*path ? "rock.obj: no such file" : "must name a file"));
        }
    }
    // A symlink loop says so (exists() is false for it too; it was "no such file").
    std::filesystem::remove(dir / "a.obj"), std::filesystem::remove(dir / "b.obj");
    std::filesystem::create_symlink("b.obj", dir / "a.obj");
    std::filesystem::create_symlink("a.obj", dir / "b.obj");
    s["geometry"][1]["source"]["path"] = "a.obj";
    try {
        openSceneGeometry(parseScene(s, (dir / "scene.json").string()));
        FAIL("no error");
    } catch (const InputError& e) {
        CHECK_THAT(std::string(e.what()), Catch::Contains("a.obj: Too many levels of symbolic links"));
    }
    std::filesystem::remove_all(dir);
}

TEST_CASE("a sun's radiance, like every light's, may be one number for grey", "[scene]") {
    json s = minimal();
    s["lights"][0] = {{"type", "sun"}, {"direction", {0, -1, 0}}, {"radiance", 20000}};
    const SceneDesc grey = parseScene(s, "dir/scene.json");
    s["lights"][0]["radiance"] = {20000, 20000, 20000};
    const SceneDesc rgb = parseScene(s, "dir/scene.json");
    CHECK(grey.lights[0].irradiance == rgb.lights[0].irradiance);
    CHECK(grey.lights[0].irradiance.x > 0);
    s["lights"][0]["radiance"] = -1;
    requireError(s, "lights[0].radiance: must be finite and non-negative");
}

TEST_CASE("unknown geometry types and bad generator parameters name the entry", "[scene]") {
    registerFileSourceTypes();
    registerProceduralGenerators();
    json s = minimal();
    s["geometry"][0] = {{"type", "teapotz"}};
    SceneDesc scene = parseScene(s, "dir/scene.json");
    CHECK_THROWS_WITH(openSceneGeometry(scene), Catch::Contains("geometry[0]") && Catch::Contains("unknown geometry type"));
    s["geometry"][0] = {{"type", "grid"}, {"bar", 2}};
    scene = parseScene(s, "dir/scene.json");
    CHECK_THROWS_WITH(openSceneGeometry(scene), Catch::Contains("geometry[0].bar"));
    s["geometry"][0] = {{"type", "obj"}, {"path", "missing.obj"}};
    scene = parseScene(s, "dir/scene.json");
    CHECK_THROWS_WITH(openSceneGeometry(scene), Catch::Contains("missing.obj"));
}

TEST_CASE("the closed key marks or unmarks every triangle of an entry", "[scene]") {
    registerProceduralGenerators();
    json s = minimal();
    auto flagsOf = [&](const json& entry) {
        s["geometry"] = json::array({entry});
        std::vector<uint32_t> flags;
        for (const Triangle& t : readAll(*openSceneGeometry(parseScene(s, "dir/scene.json")))) flags.push_back(t.flags);
        return flags;
    };
    const json grid = {{"type", "grid"}, {"cells", 2}, {"levels", 1}, {"thickness", 0.05}, {"floor_size", 4}};
    std::vector<uint32_t> plain = flagsOf(grid);  // the generator marks its bars, not its floor
    REQUIRE(plain.size() == 2u + 9u * 12);
    CHECK(plain[0] == 0u);
    CHECK(plain[2] == (kTriangleClosed | kTriangleSolidStart));  // each bar is a solid of its own
    CHECK(plain[3] == kTriangleClosed);
    json closed = grid, open = grid;
    closed["closed"] = true, open["closed"] = false;
    // Marked closed, the entry is one solid at least (its first triangle starts one); the bars
    // keep their own starts.
    std::vector<uint32_t> marked = flagsOf(closed);
    for (uint32_t f : marked) CHECK((f & kTriangleClosed) != 0u);
    CHECK((marked[0] & kTriangleSolidStart) != 0u);
    CHECK((marked[2] & kTriangleSolidStart) != 0u);
    for (uint32_t f : flagsOf(open)) CHECK(f == 0u);
    s["geometry"][0]["closed"] = "yes";
    CHECK_THROWS_WITH(parseScene(s, "dir/scene.json"), Catch::Contains("geometry[0].closed"));
}

TEST_CASE("a polygon light typed to four decimals is flattened onto its plane, and one farther off names its vertex", "[scene]") {
    // A pentagon of radius 1 turned 37 degrees, to four decimals: 3.6e-6 off its plane, refused
    // at 1e-6 of its size, with the first vertex tested named.
    json s = minimal();
    s["lights"][0] = json::parse(R"({"type": "polygon", "vertices": [[0.309, 3.5724, 0.7596], [-0.809, 3.3538, 0.4695],
        [-0.809, 2.6462, -0.4695], [0.309, 2.4276, -0.7596], [1.0, 3.0, 0.0]]})");
    const SceneDesc scene = parseScene(s, "dir/scene.json");
    const std::vector<glm::dvec3>& p = scene.lights[0].polygon;
    const glm::dvec3 n = glm::normalize(glm::cross(p[1] - p[0], p[2] - p[0]));
    for (const glm::dvec3& q : p) CHECK(std::abs(glm::dot(q - p[0], n)) < 1e-12);  // one plane now
    CHECK(glm::length(p[4] - glm::dvec3(1.0, 3.0, 0.0)) < 1e-5);                      // and barely moved
    // An exactly planar polygon keeps its bits.
    s["lights"][0] = json::parse(R"({"type": "polygon", "vertices": [[0, 3, 1], [0.5, 3, 1.5], [1, 3, 1], [1, 3, 0], [0, 3, 0]]})");
    CHECK(parseScene(s, "dir/scene.json").lights[0].polygon[1] == glm::dvec3(0.5, 3, 1.5));
    s["lights"][0]["vertices"][3] = {1, 3.1, 0};
    requireError(s, "lights[0]: polygon vertex 3 is 0.0319 off the plane of the vertices (at most 0.000");
}

TEST_CASE("a light's zero area is judged relative to its size: a micrometre light is a light", "[scene]") {
    json s = minimal();
    s["lights"][0]["u"] = {1e-6, 0, 0}, s["lights"][0]["v"] = {0, 0, 1e-6};  // area 1e-12
    CHECK_NOTHROW(parseScene(s, "dir/scene.json"));
    s["lights"][0] = json::parse(R"({"type": "polygon", "vertices": [[0, 1e-6, 0], [1e-6, 1e-6, 0], [0, 1e-6, 1e-6]]})");
    CHECK_NOTHROW(parseScene(s, "dir/scene.json"));
    s = minimal();
    s["lights"][0]["u"] = {1e-6, 0, 0}, s["lights"][0]["v"] = {2e-6, 1e-18, 0};  // parallel to roundoff
    requireError(s, "lights[0]: zero-area light");
    s = minimal();
    s["lights"][0] = json::parse(R"({"type": "polygon", "vertices": [[0, 0, 0], [1e-6, 0, 0], [2e-6, 1e-18, 0]]})");
    requireError(s, "lights[0]: zero-area light");
}
