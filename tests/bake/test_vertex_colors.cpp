// The "vertices" receiver kind: a baked copy of the input glTF, read back through tinygltf, checked
// against a points bake of the same vertices, and (when installed) the Khronos validator.

#include "CliRunner.h"
#include "GltfValidator.h"

#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "stream/util/Npy.h"

#include <tiny_gltf.h>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

using namespace penumbra;
using namespace penumbra::test;

namespace {

const std::string kFloor = std::string(PENUMBRA_SOURCE_DIR) + "/examples/vertices-floor.glb";

/// The example's floor (33 x 33 vertices, y = 0, mesh 0) and blocker (mesh 1) under a small light.
nlohmann::json sceneJson(const std::string& mesh, const std::string& output, nlohmann::json receivers = nullptr) {
    if (receivers.is_null()) receivers = {{"type", "vertices"}, {"meshes", {0}}};
    return {{"geometry", {{{"type", std::filesystem::path(mesh).extension() == ".glb" ? "glb" : "gltf"}, {"path", mesh}}}},
            {"lights", {{{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {0.5, 0, 0}}, {"v", {0, 0, 0.5}}, {"samples", 64},
                         {"sample_sets", 4}}}},
            {"receivers", receivers},
            {"output", output}};
}

nlohmann::json bake(const ScratchDir& dir, const nlohmann::json& scene) {
    registerFileSourceTypes();
    AllowOutsidePaths examples;  // the scene in the scratch directory bakes the examples' floor
    BakeSettings settings;
    settings.quiet = true;
    settings.threads = 2;
    return runBake(parseScene(scene, dir / "scene.json"), settings);
}

tinygltf::Model load(const std::string& path) {
    tinygltf::Model model;
    tinygltf::TinyGLTF loader;
    std::string err, warn;
    bool ok = path.ends_with(".glb") ? loader.LoadBinaryFromFile(&model, &err, &warn, path)
                                     : loader.LoadASCIIFromFile(&model, &err, &warn, path);
    INFO(err);
    REQUIRE(ok);
    return model;
}

/// Float accessor @p index of @p model as a flat array.
std::vector<float> floats(const tinygltf::Model& model, int index) {
    const tinygltf::Accessor& a = model.accessors[size_t(index)];
    REQUIRE(a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT);
    const tinygltf::BufferView& view = model.bufferViews[size_t(a.bufferView)];
    size_t n = a.count * size_t(tinygltf::GetNumComponentsInType(uint32_t(a.type)));
    std::vector<float> out(n);
    std::memcpy(out.data(), model.buffers[size_t(view.buffer)].data.data() + view.byteOffset + a.byteOffset, n * 4);
    return out;
}

}  // namespace

TEST_CASE("vertices: COLOR_0 and _VISIBILITY match a points bake of the same vertices", "[vertices]") {
    ScratchDir dir("vertices");
    bake(dir, sceneJson(kFloor, dir / "out/floor.glb"));
    tinygltf::Model in = load(kFloor), out = load(dir / "out/floor.glb");
    REQUIRE(out.meshes.size() == 2);
    const tinygltf::Primitive& floor = out.meshes[0].primitives[0];
    REQUIRE(floor.attributes.count("COLOR_0"));
    REQUIRE(floor.attributes.count("_VISIBILITY"));
    REQUIRE(floor.attributes.count("_IRRADIANCE"));
    REQUIRE(out.meshes[1].primitives[0].attributes.count("_VISIBILITY"));  // the blocker too
    std::vector<float> v = floats(out, floor.attributes.at("_VISIBILITY"));
    std::vector<float> colour = floats(out, floor.attributes.at("COLOR_0"));
    std::vector<float> positions = floats(in, in.meshes[0].primitives[0].attributes.at("POSITION"));
    REQUIRE(v.size() == 33 * 33);
    REQUIRE(colour.size() == 3 * v.size());
    for (size_t i = 0; i < v.size(); ++i) REQUIRE(colour[3 * i] == v[i]);
    CHECK(v[16 * 33 + 16] == 0.0f);  // (0, 0, 0), right under the blocker
    CHECK(v[0] == 1.0f);             // (-3, 0, -3), far out

    // The floor's vertices come first, so as points they get the same light sample sets.
    std::vector<float> rows;
    for (size_t i = 0; i < v.size(); ++i) rows.insert(rows.end(), {positions[3 * i], positions[3 * i + 1], positions[3 * i + 2], 0, 1, 0});
    uint64_t shape[2] = {v.size(), 6};
    writeNpy(dir / "points.npy", "<f4", shape, rows.data(), rows.size() * 4);
    bake(dir, sceneJson(kFloor, dir / "points-v.npy", {{"type", "points"}, {"path", dir / "points.npy"}}));
    NpyArray expected = readNpy(dir / "points-v.npy");
    REQUIRE(expected.shape[0] == v.size());
    std::vector<float> ev(v.size());
    std::memcpy(ev.data(), expected.data.data(), ev.size() * 4);
    CHECK(ev == v);
}

TEST_CASE("vertices: an existing COLOR_0 is kept and the result goes to _VISIBILITY, also as .gltf", "[vertices]") {
    ScratchDir dir("vertices-color");
    // A copy of the example whose floor already has vertex colours.
    tinygltf::Model model = load(kFloor);
    tinygltf::Buffer& buffer = model.buffers[0];
    tinygltf::BufferView view;
    view.buffer = 0, view.byteOffset = buffer.data.size(), view.byteLength = 33 * 33 * 12, view.target = TINYGLTF_TARGET_ARRAY_BUFFER;
    std::vector<float> grey(33 * 33 * 3, 0.5f);
    buffer.data.insert(buffer.data.end(), reinterpret_cast<unsigned char*>(grey.data()),
                       reinterpret_cast<unsigned char*>(grey.data() + grey.size()));
    model.bufferViews.push_back(view);
    tinygltf::Accessor accessor;
    accessor.bufferView = int(model.bufferViews.size() - 1), accessor.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    accessor.type = TINYGLTF_TYPE_VEC3, accessor.count = 33 * 33;
    model.accessors.push_back(accessor);
    const int colourAccessor = int(model.accessors.size() - 1);
    model.meshes[0].primitives[0].attributes["COLOR_0"] = colourAccessor;
    tinygltf::TinyGLTF writer;
    REQUIRE(writer.WriteGltfSceneToFile(&model, dir / "coloured.glb", false, true, false, true));

    bake(dir, sceneJson(dir / "coloured.glb", dir / "out/coloured.gltf"));
    tinygltf::Model out = load(dir / "out/coloured.gltf");
    const auto& attributes = out.meshes[0].primitives[0].attributes;
    REQUIRE(attributes.at("COLOR_0") == colourAccessor);
    CHECK(floats(out, colourAccessor) == grey);
    std::vector<float> v = floats(out, attributes.at("_VISIBILITY"));
    CHECK(v[16 * 33 + 16] == 0.0f);
    CHECK(v[0] == 1.0f);
    CHECK(out.meshes[1].primitives[0].attributes.count("COLOR_0"));  // the blocker had none

    std::string validatorDir, log;
    if (!validatorAvailable(validatorDir)) {
        WARN("skipped: gltf-validator not installed under " << validatorDir << " (./setup.sh installs it)");
        return;
    }
    bake(dir, sceneJson(kFloor, dir / "out/floor.glb"));
    for (const std::string& file : {dir / "out/coloured.gltf", dir / "out/floor.glb"}) {
        int code = validateGltf(file, validatorDir, log);
        INFO(log);
        CHECK(code == 0);
    }
}

TEST_CASE("vertices: the copy keeps the scene entry's transform and the colours baked at that size", "[vertices]") {
    ScratchDir dir("vertices-transform");
    nlohmann::json scene = sceneJson(kFloor, dir / "out/big.glb");
    scene["geometry"][0]["transform"] = {{"scale", 10}, {"translate", {1, -2, 3}}};
    scene["lights"][0]["center"] = {0, 40, 0};
    bake(dir, scene);
    tinygltf::Model in = load(kFloor), out = load(dir / "out/big.glb");
    // One root per scene above the original roots, holding the entry's matrix (column-major).
    REQUIRE(out.scenes.size() == in.scenes.size());
    const tinygltf::Node& root = out.nodes[size_t(out.scenes[0].nodes.at(0))];
    CHECK(out.scenes[0].nodes.size() == 1);
    CHECK(root.children == in.scenes[0].nodes);
    REQUIRE(root.matrix.size() == 16);
    CHECK(root.matrix[0] == 10.0);
    CHECK(root.matrix[5] == 10.0);
    CHECK(root.matrix[10] == 10.0);
    CHECK(root.matrix[12] == 1.0);
    CHECK(root.matrix[13] == -2.0);
    CHECK(root.matrix[14] == 3.0);
    // The same vertices as in an untransformed bake under a light scaled alike see the same sky.
    std::vector<float> v = floats(out, out.meshes[0].primitives[0].attributes.at("_VISIBILITY"));
    CHECK(v[0] == 1.0f);
    CHECK(v[16 * 33 + 16] == 0.0f);
    if (std::string validator, log; validatorAvailable(validator)) {
        const int code = validateGltf(dir / "out/big.glb", validator, log);
        INFO(log);
        CHECK(code == 0);
    }
}

TEST_CASE("vertices: \"color_format\": \"unorm16\" writes COLOR_0 as normalized unsigned shorts", "[vertices]") {
    ScratchDir dir("vertices-unorm");
    bake(dir, sceneJson(kFloor, dir / "out/f.glb", {{"type", "vertices"}, {"meshes", {0}}, {"color_format", "unorm16"}}));
    tinygltf::Model out = load(dir / "out/f.glb");
    const tinygltf::Primitive& floor = out.meshes[0].primitives[0];
    const tinygltf::Accessor& a = out.accessors[size_t(floor.attributes.at("COLOR_0"))];
    CHECK(a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
    CHECK(a.normalized);
    const tinygltf::BufferView& view = out.bufferViews[size_t(a.bufferView)];
    REQUIRE(view.byteStride == 8);  // each element 4-byte aligned, as glTF requires
    std::vector<float> v = floats(out, floor.attributes.at("_VISIBILITY"));
    const unsigned char* base = out.buffers[size_t(view.buffer)].data.data() + view.byteOffset + a.byteOffset;
    for (size_t i = 0; i < v.size(); ++i) {
        uint16_t c[3];
        std::memcpy(c, base + 8 * i, sizeof(c));
        REQUIRE(c[0] == uint16_t(std::lround(double(v[i]) * 65535.0)));
        REQUIRE(c[1] == c[0]);
        REQUIRE(c[2] == c[0]);
    }
    if (std::string validator, log; validatorAvailable(validator)) {
        const int code = validateGltf(dir / "out/f.glb", validator, log);
        INFO(log);
        CHECK(code == 0);
    }
    CHECK_THROWS_WITH(bake(dir, sceneJson(kFloor, dir / "out/g.glb", {{"type", "vertices"}, {"meshes", {0}}, {"color_format", "u8"}})),
                      Catch::Contains("receivers.color_format"));
}

TEST_CASE("vertices: bad parameters are one-line errors naming the key", "[vertices]") {
    ScratchDir dir("vertices-errors");
    auto error = [&](nlohmann::json receivers, const std::string& output = "out.glb", const std::string& mesh = kFloor) {
        AllowOutsidePaths examples;
        return errorOf([&] { parseScene(sceneJson(mesh, output, receivers), dir / "scene.json"); });
    };
    CHECK_THAT(error({{"type", "vertices"}}), Catch::Contains("receivers.meshes") && Catch::Contains("missing"));
    CHECK_THAT(error({{"type", "vertices"}, {"meshes", {3}}}),
               Catch::Contains("receivers.meshes[0]") && Catch::Contains("out of range"));
    CHECK_THAT(error({{"type", "vertices"}, {"meshes", "all"}}), Catch::Contains("receivers.meshes"));
    CHECK_THAT(error({{"type", "vertices"}, {"meshes", {0}}, {"colour", 1}}), Catch::Contains("receivers.colour"));
    CHECK_THAT(error({{"type", "vertices"}, {"meshes", {0}}}, "out.exr"), Catch::Contains("output"));
    std::ofstream(dir / "tri.obj") << "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n";
    nlohmann::json scene = sceneJson(kFloor, "out.glb");
    scene["geometry"][0] = {{"type", "obj"}, {"path", dir / "tri.obj"}};
    AllowOutsidePaths examples;
    CHECK_THAT(errorOf([&] { parseScene(scene, dir / "scene.json"); }),
               Catch::Contains("receivers.meshes[0]") && Catch::Contains(".gltf or .glb"));
}

TEST_CASE("vertices: the example bakes with one command", "[vertices]") {
    ScratchDir dir("vertices-example");
    RunResult r = runPenumbra("bake " + std::string(PENUMBRA_SOURCE_DIR) + "/examples/vertices.json --quiet -o " + (dir / "v.glb"));
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    tinygltf::Model out = load(dir / "v.glb");
    CHECK(out.meshes[0].primitives[0].attributes.count("COLOR_0"));
}

TEST_CASE("vertices: a mesh drawn by two nodes is an error naming the file", "[vertices]") {
    ScratchDir dir("vertices-instanced");
    tinygltf::Model model = load(kFloor);
    tinygltf::Node copy;
    copy.mesh = 1;
    copy.translation = {2, 0, 0};
    model.nodes.push_back(copy);
    model.scenes[0].nodes.push_back(int(model.nodes.size() - 1));
    tinygltf::TinyGLTF writer;
    REQUIRE(writer.WriteGltfSceneToFile(&model, dir / "twice.glb", false, true, false, true));
    CHECK_THAT(errorOf([&] { bake(dir, sceneJson(dir / "twice.glb", dir / "out.glb")); }),
               Catch::Contains("twice.glb") && Catch::Contains("mesh 1 is drawn by nodes 1 and 2"));
    CHECK(!std::filesystem::exists(dir / "out.glb"));
}

TEST_CASE("vertices: primitives sharing one POSITION accessor share its receivers and result accessors", "[vertices]") {
    // The floor's triangles split into 64 primitives over the same vertices: the bake must give
    // each vertex one receiver (not one per primitive: that grew as primitives x vertices), the
    // same values as the unsplit floor, and one set of result accessors for all of them.
    ScratchDir dir("vertices-shared");
    tinygltf::Model model = load(kFloor);
    tinygltf::Primitive whole = model.meshes[0].primitives.at(0);
    const tinygltf::Accessor indices = model.accessors.at(size_t(whole.indices));
    const size_t triangles = indices.count / 3, parts = 64;
    const size_t bytes = size_t(tinygltf::GetComponentSizeInBytes(uint32_t(indices.componentType)));
    model.meshes[0].primitives.clear();
    for (size_t k = 0; k < parts; ++k) {
        const size_t first = triangles * k / parts, end = triangles * (k + 1) / parts;
        tinygltf::Accessor part = indices;
        part.byteOffset = indices.byteOffset + 3 * first * bytes;
        part.count = 3 * (end - first);
        part.minValues.clear(), part.maxValues.clear();
        model.accessors.push_back(part);
        tinygltf::Primitive p = whole;
        p.indices = int(model.accessors.size() - 1);
        model.meshes[0].primitives.push_back(p);
    }
    tinygltf::TinyGLTF writer;
    REQUIRE(writer.WriteGltfSceneToFile(&model, dir / "split.glb", false, true, false, true));
    const nlohmann::json split = bake(dir, sceneJson(dir / "split.glb", dir / "split-out.glb"));
    const nlohmann::json plain = bake(dir, sceneJson(kFloor, dir / "plain-out.glb"));
    CHECK(split["receivers"] == plain["receivers"]);
    const tinygltf::Model a = load(dir / "split-out.glb"), b = load(dir / "plain-out.glb");
    REQUIRE(a.meshes[0].primitives.size() == parts);
    const int shared = a.meshes[0].primitives[0].attributes.at("_VISIBILITY");
    for (const tinygltf::Primitive& p : a.meshes[0].primitives) {
        CHECK(p.attributes.at("_VISIBILITY") == shared);
        CHECK(p.attributes.at("COLOR_0") == a.meshes[0].primitives[0].attributes.at("COLOR_0"));
    }
    CHECK(floats(a, shared) == floats(b, b.meshes[0].primitives[0].attributes.at("_VISIBILITY")));
}

TEST_CASE("vertices: a zero NORMAL takes its faces' normal, with a warning, not a receiver without cosine", "[vertices]") {
    // A zero normal (invalid glTF) was taken as "no receiver cosine": 0.0810 where a vertex at
    // the same place with its normal got 0.0731. The floor is flat: its face normal is the one
    // the file gives, so the results must be those of the file as it was.
    ScratchDir dir("vertices-zero-normal");
    tinygltf::Model model = load(kFloor);
    tinygltf::Primitive& floor = model.meshes[0].primitives[0];
    REQUIRE(floor.attributes.count("NORMAL"));
    const tinygltf::Accessor& normals = model.accessors[size_t(floor.attributes.at("NORMAL"))];
    const tinygltf::BufferView& view = model.bufferViews[size_t(normals.bufferView)];
    REQUIRE((view.byteStride == 0 || view.byteStride == 12));
    float* n = reinterpret_cast<float*>(model.buffers[size_t(view.buffer)].data.data() + view.byteOffset + normals.byteOffset);
    for (const size_t v : {size_t(0), size_t(16 * 33 + 16), size_t(16 * 33 + 20)}) n[3 * v] = n[3 * v + 1] = n[3 * v + 2] = 0.f;
    tinygltf::TinyGLTF writer;
    REQUIRE(writer.WriteGltfSceneToFile(&model, dir / "zero.glb", false, true, false, true));
    bake(dir, sceneJson(kFloor, dir / "out/floor.glb"));
    std::ofstream(dir / "zero.json") << sceneJson(dir / "zero.glb", dir / "out/zero.glb").dump();
    RunResult r = runPenumbra("bake " + (dir / "zero.json") + " -q --threads 2");
    CHECK(r.exitCode == 0);
    CHECK_THAT(r.err, Catch::Contains("zero.glb: mesh 0 primitive 0: 3 vertex NORMAL(s) of zero length take their faces' normal"));
    const tinygltf::Model a = load(dir / "out/floor.glb"), b = load(dir / "out/zero.glb");
    for (const char* attribute : {"_IRRADIANCE", "_VISIBILITY"}) {
        INFO(attribute);
        CHECK(floats(a, a.meshes[0].primitives[0].attributes.at(attribute)) == floats(b, b.meshes[0].primitives[0].attributes.at(attribute)));
    }
}
