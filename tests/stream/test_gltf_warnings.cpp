// A glTF file's warnings reach the user once per command, though a bake loads the document more
// than once (alpha planning, the blocker stream, receiver meshes).

#include "CliRunner.h"

#include <catch2/catch.hpp>

#include <fstream>

using namespace penumbra::test;

TEST_CASE("glTF warnings: a node with both a matrix and TRS is warned of once per bake", "[gltf][cli][warnings]") {
    ScratchDir dir("gltf-warnings");
    // One triangle, its node with both a matrix and a translation; base64 of three float VEC3s.
    std::ofstream(dir / "warn.gltf") << R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],
        "nodes":[{"mesh":0,"matrix":[1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1],"translation":[1,0,0]}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
        "buffers":[{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],
        "bufferViews":[{"buffer":0,"byteLength":36}],
        "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}]})";
    std::ofstream(dir / "scene.json") << R"({"geometry": [{"type": "gltf", "path": "warn.gltf"}],
        "lights": [{"type": "rect", "center": [0, 5, 0], "u": [1, 0, 0], "v": [0, 0, 1], "samples": 16}],
        "receivers": {"type": "camera", "eye": [0, 3, 4], "target": [0, 0, 0], "width": 16, "height": 12},
        "output": "out/x.exr"})";
    const RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q");
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    CHECK(occurrences(r.err, "have both a matrix and a translation") == 1);
}

TEST_CASE("glTF warnings: morph targets at non-zero weights and skins are not applied, and say so once", "[gltf][cli][warnings]") {
    ScratchDir dir("gltf-unposed");
    // One triangle with a morph target (POSITION deltas: the same accessor) and a skinned node
    // holding it again; the weights are the mesh's default, then a node's override.
    auto write = [&](const std::string& name, const std::string& meshWeights, const std::string& node) {
        std::ofstream(dir / name) << R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],
            "nodes":[)" + node + R"(],
            "meshes":[{"primitives":[{"attributes":{"POSITION":0},"targets":[{"POSITION":0}]}])" + meshWeights + R"(}],
            "buffers":[{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],
            "bufferViews":[{"buffer":0,"byteLength":36}],
            "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}]})";
    };
    write("rest.gltf", R"(,"weights":[0])", R"({"mesh":0})");                 // weight 0: what viewers show too
    write("mesh-weight.gltf", R"(,"weights":[0.5])", R"({"mesh":0})");
    write("node-weight.gltf", "", R"({"mesh":0,"weights":[1]})");
    write("skinned.gltf", "", R"({"mesh":0,"skin":0})");
    for (const auto& [file, morph, skin] : {std::tuple{"rest.gltf", 0, 0}, std::tuple{"mesh-weight.gltf", 1, 0},
                                            std::tuple{"node-weight.gltf", 1, 0}, std::tuple{"skinned.gltf", 0, 1}}) {
        std::ofstream(dir / "scene.json") << R"({"geometry": [{"type": "gltf", "path": ")" + std::string(file) + R"("}],
            "lights": [{"type": "rect", "center": [0, 5, 0], "u": [1, 0, 0], "v": [0, 0, 1], "samples": 16}],
            "receivers": {"type": "camera", "eye": [0, 3, 4], "target": [0, 0, 0], "width": 16, "height": 12},
            "output": "out/x.exr"})";
        const RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q");
        INFO(file << ": " << r.err);
        CHECK(occurrences(r.err, "morph targets are not applied") == morph);
        CHECK(occurrences(r.err, "skins are not applied") == skin);
    }
}
