// The receiver-kind contract (bake/kinds/ReceiverKind.h): parseScene checks "receivers" without
// making the kind, a bake makes it once, and a lightmap's meshes, which the check must load to
// judge (their UVs), are loaded once per bake: handed from the check to the bake of the same
// scene, and loaded again when a file changed in between.

#include "LightmapTestMeshes.h"
#include "TestSupport.h"

#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "bake/kinds/ReceiverKind.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

using namespace penumbra;
using namespace penumbra::test;

namespace {

nlohmann::json lightmapScene() {
    return nlohmann::json::parse(R"({"geometry": [{"type": "obj", "path": "quad.obj", "transform": {"scale": 4, "translate": [-2, 0, 2]}}],
        "lights": [{"type": "rect", "center": [0, 3, 0], "u": [1, 0, 0], "v": [0, 0, 1], "samples": 16}],
        "receivers": {"type": "lightmap", "meshes": [0], "resolution": 16, "uv": "mesh"},
        "output": "out/lightmap.exr"})");
}

nlohmann::json bakeStats(const SceneDesc& scene) {
    BakeSettings settings;
    settings.quiet = true;
    settings.threads = 1;
    return runBake(scene, settings);
}

}  // namespace

TEST_CASE("receiver kinds: a lightmap's meshes are loaded by the scene check and handed to the bake", "[kinds][lightmap]") {
    registerFileSourceTypes();
    ScratchDir dir("kinds-once");
    writeText(dir / "quad.obj", kQuadObj);
    const SceneDesc scene = parseScene(lightmapScene(), dir / "scene.json");
    CHECK(bakeStats(scene)["lightmap"]["meshes_loaded_by"] == "scene check");
    // The check's meshes went to the first bake: a second bake of the same scene loads its own.
    CHECK(bakeStats(scene)["lightmap"]["meshes_loaded_by"] == "bake");
}

TEST_CASE("receiver kinds: a mesh file changed after the check is loaded again by the bake", "[kinds][lightmap]") {
    registerFileSourceTypes();
    ScratchDir dir("kinds-changed");
    writeText(dir / "quad.obj", kQuadObj);
    const SceneDesc scene = parseScene(lightmapScene(), dir / "scene.json");
    {
        std::ofstream(dir / "quad.obj", std::ios::app) << "# edited after the check\n";
    }
    CHECK(bakeStats(scene)["lightmap"]["meshes_loaded_by"] == "bake");
}

TEST_CASE("receiver kinds: validation reads every key and makes nothing", "[kinds]") {
    ScratchDir dir("kinds-validate");
    SceneDesc scene;
    scene.file = dir / "scene.json";
    scene.baseDir = dir.path;
    scene.output = (dir / "out.exr");
    CHECK_NOTHROW(validateReceiverKind(nlohmann::json::parse(R"({"type": "camera", "eye": [0, 1, 2], "target": [0, 0, 0]})"), scene));
    CHECK_THROWS_WITH(
        validateReceiverKind(nlohmann::json::parse(R"({"type": "camera", "eye": [0, 1, 2], "target": [0, 0, 0], "fov": 40})"), scene),
        Catch::Contains("receivers.fov"));
    CHECK_THROWS_WITH(validateReceiverKind(nlohmann::json::parse(R"({"type": "camera", "eye": [0, 0, 0], "target": [0, 0, 0]})"), scene),
                      Catch::Contains("receivers"));
    CHECK(makeReceiverKind(nlohmann::json::parse(R"({"type": "camera", "eye": [0, 1, 2], "target": [0, 0, 0]})"), scene) != nullptr);
}
