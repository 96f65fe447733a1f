// Tests for the glTF reader: primitive modes, index and position encodings, the node
// hierarchy, validation messages, tinygltf's malformed samples, and damaged .glb files.

#include "stream/util/Error.h"
#include "stream/GltfDocument.h"
#include "stream/GltfReader.h"
#include "GltfModelBuilder.h"
#include "StreamTestFiles.h"

#include <catch2/catch.hpp>

#include <tiny_gltf.h>

#include <glm/gtc/matrix_transform.hpp>

#include <cmath>
#include <limits>
#include <sstream>

using namespace penumbra;
using namespace penumbra::test;

namespace {

const std::vector<glm::vec3> kFive = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0, 2, 0}};

std::vector<Triangle> readGltf(const std::string& path) { return readAll(*openGltf(path)); }

std::string gltfError(const std::string& path) {
    try {
        readGltf(path);
    } catch (const InputError& e) {
        return e.what();
    }
    return "no error";
}

bool near(glm::vec3 a, glm::vec3 b, float eps = 1e-5f) { return glm::all(glm::lessThanEqual(glm::abs(a - b), glm::vec3(eps))); }

}  // namespace

TEST_CASE("glTF: non-indexed float triangles read back bit-exact", "[stream][gltf]") {
    ScratchDir dir("gltf");
    std::vector<glm::vec3> points = {{0.1f, -0.0f, 3e-39f}, {1e30f, 2, 3}, {-4, 5.5f, 6}, {7, 8, 9}, {1, 1, 1}, {2, 2, 2}};
    ModelBuilder b;
    std::string path = single(b, dir, primitive(b.positions(points)));
    TriangleSourcePtr source = openGltf(path);
    CHECK(source->sizeHint() == 2u);
    CHECK(source->name() == path);
    std::vector<Triangle> tris = readAll(*source);
    REQUIRE(tris.size() == 2);
    CHECK(sameBits(tris[0], tri(points[0], points[1], points[2])));
    CHECK(sameBits(tris[1], tri(points[3], points[4], points[5])));
    source->rewind();
    CHECK(sameBits(readAll(*source), tris));
}

TEST_CASE("glTF: byte, short and int indices", "[stream][gltf]") {
    ScratchDir dir("gltf");
    std::vector<Triangle> expected = {tri(kFive[0], kFive[1], kFive[2]), tri(kFive[2], kFive[1], kFive[3]),
                                      tri(kFive[4], kFive[2], kFive[3])};
    std::vector<uint32_t> order = {0, 1, 2, 2, 1, 3, 4, 2, 3};
    for (int width : {1, 2, 4}) {
        ModelBuilder b;
        int pos = b.positions(kFive);
        int idx = width == 1   ? b.indices(std::vector<uint8_t>(order.begin(), order.end()))
                  : width == 2 ? b.indices(std::vector<uint16_t>(order.begin(), order.end()))
                               : b.indices(order);
        INFO("index width " << width);
        CHECK(sameBits(readGltf(single(b, dir, primitive(pos, idx))), expected));
    }
}

TEST_CASE("glTF: strips alternate winding, fans pivot on the first vertex", "[stream][gltf]") {
    ScratchDir dir("gltf");
    const auto& v = kFive;
    {
        ModelBuilder b;
        auto tris = readGltf(single(b, dir, primitive(b.positions(v), -1, TINYGLTF_MODE_TRIANGLE_STRIP)));
        REQUIRE(tris.size() == 3);
        CHECK(sameBits(tris[0], tri(v[0], v[1], v[2])));
        CHECK(sameBits(tris[1], tri(v[1], v[3], v[2])));
        CHECK(sameBits(tris[2], tri(v[2], v[3], v[4])));
    }
    {
        ModelBuilder b;
        auto tris = readGltf(single(b, dir, primitive(b.positions(v), -1, TINYGLTF_MODE_TRIANGLE_FAN)));
        REQUIRE(tris.size() == 3);
        CHECK(sameBits(tris[0], tri(v[1], v[2], v[0])));
        CHECK(sameBits(tris[1], tri(v[2], v[3], v[0])));
        CHECK(sameBits(tris[2], tri(v[3], v[4], v[0])));
    }
    {  // indexed strip: the strip runs through the index list
        ModelBuilder b;
        int pos = b.positions(v);
        auto tris = readGltf(single(b, dir, primitive(pos, b.indices(std::vector<uint16_t>{4, 3, 2, 1}),
                                                      TINYGLTF_MODE_TRIANGLE_STRIP)));
        REQUIRE(tris.size() == 2);
        CHECK(sameBits(tris[0], tri(v[4], v[3], v[2])));
        CHECK(sameBits(tris[1], tri(v[3], v[1], v[2])));
    }
    {  // fewer than three vertices make no triangles
        ModelBuilder b;
        int pos = b.positions({v[0], v[1]});
        TriangleSourcePtr s = openGltf(single(b, dir, primitive(pos, -1, TINYGLTF_MODE_TRIANGLE_STRIP)));
        CHECK(s->sizeHint() == 0u);
        CHECK(readAll(*s).empty());
    }
}

TEST_CASE("glTF: quantized positions (KHR_mesh_quantization)", "[stream][gltf]") {
    ScratchDir dir("gltf");
    struct Case {
        int componentType;
        bool normalized;
        std::vector<uint8_t> bytes;  // three vertices, each padded to a 4-byte stride
        size_t stride;
        std::vector<glm::vec3> expected;
    };
    auto i8 = [](int x) { return uint8_t(int8_t(x)); };
    auto le16 = [](int x) { return std::vector<uint8_t>{uint8_t(x & 0xff), uint8_t((x >> 8) & 0xff)}; };
    auto shorts = [&](std::vector<int> values) {  // 3 shorts per vertex + 2 bytes padding
        std::vector<uint8_t> out;
        for (size_t i = 0; i < values.size(); ++i) {
            auto b = le16(values[i]);
            out.insert(out.end(), b.begin(), b.end());
            if (i % 3 == 2) out.insert(out.end(), {0, 0});
        }
        return out;
    };
    std::vector<Case> cases = {
        {TINYGLTF_COMPONENT_TYPE_BYTE, true, {i8(127), i8(-127), i8(-128), 0, 0, i8(64), 0, 0, 1, 2, 3, 0}, 4,
         {{1, -1, -1}, {0, 64 / 127.0f, 0}, {1 / 127.0f, 2 / 127.0f, 3 / 127.0f}}},
        {TINYGLTF_COMPONENT_TYPE_BYTE, false, {i8(-5), 6, 7, 0, 0, 0, 1, 0, 1, 0, 0, 0}, 4, {{-5, 6, 7}, {0, 0, 1}, {1, 0, 0}}},
        {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, true, {255, 0, 51, 0, 0, 255, 0, 0, 0, 0, 255, 0}, 4,
         {{1, 0, 0.2f}, {0, 1, 0}, {0, 0, 1}}},
        {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, false, {200, 0, 0, 0, 0, 200, 0, 0, 0, 0, 200, 0}, 4,
         {{200, 0, 0}, {0, 200, 0}, {0, 0, 200}}},
        {TINYGLTF_COMPONENT_TYPE_SHORT, true, shorts({32767, -32767, -32768, 0, 0, 16384, 0, 1, 0}), 8,
         {{1, -1, -1}, {0, 0, 16384 / 32767.0f}, {0, 1 / 32767.0f, 0}}},
        {TINYGLTF_COMPONENT_TYPE_SHORT, false, shorts({-300, 0, 0, 0, 300, 0, 0, 0, 7}), 8,
         {{-300, 0, 0}, {0, 300, 0}, {0, 0, 7}}},
        {TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, true, shorts({65535, 0, 0, 0, 65535, 0, 0, 0, 13107}), 8,
         {{1, 0, 0}, {0, 1, 0}, {0, 0, 0.2f}}},
        {TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, false, shorts({60000, 0, 0, 0, 2, 0, 0, 0, 3}), 8,
         {{60000, 0, 0}, {0, 2, 0}, {0, 0, 3}}},
    };
    for (const Case& c : cases) {
        INFO("componentType " << c.componentType << (c.normalized ? " normalized" : ""));
        ModelBuilder b;
        b.model.extensionsUsed.push_back("KHR_mesh_quantization");
        int pos = b.accessor(b.view(c.bytes, c.stride), c.componentType, TINYGLTF_TYPE_VEC3, 3, c.normalized);
        auto tris = readGltf(single(b, dir, primitive(pos)));
        REQUIRE(tris.size() == 1);
        for (int k = 0; k < 3; ++k) CHECK(near(tris[0].v[k], c.expected[size_t(k)], 1e-7f));
        // Without the extension declared, glTF 2.0 requires FLOAT: integers were read as garbage.
        b.model.extensionsUsed.clear();
        CHECK_THROWS_WITH(readGltf(single(b, dir, primitive(pos), "plain.glb")),
                          Catch::Contains("POSITION accessor 0 has componentType " + std::to_string(c.componentType) +
                                          ", not FLOAT, and the file does not declare KHR_mesh_quantization"));
    }
}

TEST_CASE("glTF: a node with both a matrix and TRS uses the matrix, as viewers do", "[stream][gltf]") {
    ScratchDir dir("gltf");
    for (bool defaults : {false, true}) {
        ModelBuilder b;
        int mesh = b.mesh({primitive(b.positions({{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}))});
        tinygltf::Node& node = b.node(mesh);
        node.matrix = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 5, 1};
        node.translation = defaults ? std::vector<double>{0, 0, 0} : std::vector<double>{10, 0, 0};
        node.scale = {1, 1, 1};
        b.scene({0});
        const std::string path = b.save(dir, defaults ? "defaults.glb" : "both.glb");
        // The matrix either way, and a warning when the TRS says something.
        CHECK(loadGltfDocument(path).nodes[0].matrixOverTrs == !defaults);
        auto tris = readGltf(path);
        REQUIRE(tris.size() == 1);
        CHECK(tris[0].v[0] == glm::vec3(1, 0, 5));
    }
}

TEST_CASE("glTF: node TRS, matrices and hierarchy compose parent to child", "[stream][gltf]") {
    ScratchDir dir("gltf");
    ModelBuilder b;
    int mesh = b.mesh({primitive(b.positions({{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}))});

    // Node 0: translation (10, 0, 0), rotation 90 degrees about Z, scale 2; its child node 1
    // has a matrix translating by (0, 0, 5); node 2 is a second, untransformed instance.
    tinygltf::Node& parent = b.node(mesh, {1});
    parent.translation = {10, 0, 0};
    parent.rotation = {0, 0, std::sin(M_PI / 4), std::cos(M_PI / 4)};
    parent.scale = {2, 2, 2};
    tinygltf::Node& child = b.node(mesh);
    child.matrix = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 5, 1};  // column-major
    b.node(mesh);
    b.scene({0, 2});

    TriangleSourcePtr source = openGltf(b.save(dir, "trs.gltf"));
    CHECK(source->sizeHint() == 3u);
    auto tris = readAll(*source);
    REQUIRE(tris.size() == 3);
    // parent: p -> T * Rz(90) * 2p
    CHECK(near(tris[0].v[0], {10, 2, 0}));
    CHECK(near(tris[0].v[1], {8, 0, 0}));
    CHECK(near(tris[0].v[2], {10, 0, 2}));
    // child: parent * (p + (0, 0, 5))
    CHECK(near(tris[1].v[0], {10, 2, 10}));
    CHECK(near(tris[1].v[2], {10, 0, 12}));
    // the untransformed instance is bit-exact
    CHECK(sameBits(tris[2], tri({1, 0, 0}, {0, 1, 0}, {0, 0, 1})));
}

TEST_CASE("glTF: a mirroring node reverses the winding", "[stream][gltf]") {
    ScratchDir dir("gltf");
    ModelBuilder b;
    int mesh = b.mesh({primitive(b.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}))});
    b.node(mesh).scale = {-1, 1, 1};
    b.scene({0});
    auto tris = readGltf(b.save(dir, "mirror.glb"));
    REQUIRE(tris.size() == 1);
    // Mirrored in x the triangle's front still faces +Z, so the emitted order must keep +Z.
    glm::vec3 n = glm::cross(tris[0].v[1] - tris[0].v[0], tris[0].v[2] - tris[0].v[0]);
    CHECK(n.z > 0);
    CHECK(near(tris[0].v[0], {0, 0, 0}));
    CHECK(near(tris[0].v[1], {0, 1, 0}));
    CHECK(near(tris[0].v[2], {-1, 0, 0}));
}

TEST_CASE("glTF: scene selection", "[stream][gltf]") {
    ScratchDir dir("gltf");
    auto build = [](ModelBuilder& b) {
        int mesh = b.mesh({primitive(b.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}))});
        b.node(mesh).translation = {1, 0, 0};
        b.node(mesh, {2}).translation = {2, 0, 0};
        b.node(mesh).translation = {3, 0, 0};
    };
    {  // the default scene wins
        ModelBuilder b;
        build(b);
        b.scene({0});
        b.scene({1});
        b.model.defaultScene = 1;
        auto tris = readGltf(b.save(dir, "s.glb"));
        REQUIRE(tris.size() == 2);
        CHECK(tris[0].v[0].x == 2);
        CHECK(tris[1].v[0].x == 5);
    }
    {  // otherwise scene 0
        ModelBuilder b;
        build(b);
        b.scene({0});
        b.scene({1});
        auto tris = readGltf(b.save(dir, "s.glb"));
        REQUIRE(tris.size() == 1);
        CHECK(tris[0].v[0].x == 1);
    }
    {  // no scenes: every root node
        ModelBuilder b;
        build(b);
        auto tris = readGltf(b.save(dir, "s.glb"));
        REQUIRE(tris.size() == 3);
        CHECK(tris[0].v[0].x == 1);
        CHECK(tris[1].v[0].x == 2);
        CHECK(tris[2].v[0].x == 5);
    }
}

TEST_CASE("glTF: points and lines are skipped, triangles kept", "[stream][gltf]") {
    ScratchDir dir("gltf");
    ModelBuilder b;
    int pos = b.positions(kFive);
    int mesh = b.mesh({primitive(pos, -1, TINYGLTF_MODE_POINTS), primitive(pos, -1, TINYGLTF_MODE_LINE),
                       primitive(pos, -1, TINYGLTF_MODE_LINE), primitive(pos, -1, TINYGLTF_MODE_TRIANGLE_FAN)});
    b.node(mesh);
    b.scene({0});
    CHECK(readGltf(b.save(dir, "lines.glb")).size() == 3);
}

TEST_CASE("glTF: external buffers and embedded data URIs", "[stream][gltf]") {
    ScratchDir dir("gltf");
    std::vector<float> data = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    writeBytes(dir.file("tri.bin"), data.data(), data.size() * 4);
    writeText(dir.file("tri.gltf"), R"({
      "asset": {"version": "2.0"},
      "buffers": [{"uri": "tri.bin", "byteLength": 36}],
      "bufferViews": [{"buffer": 0, "byteLength": 36}],
      "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}, {"attributes": {"NORMAL": 0}}]}],
      "nodes": [{"mesh": 0}],
      "scenes": [{"nodes": [0]}]
    })");
    auto tris = readGltf(dir.file("tri.gltf"));
    REQUIRE(tris.size() == 1);
    CHECK(sameBits(tris[0], tri({0, 0, 0}, {1, 0, 0}, {0, 1, 0})));

    ModelBuilder ascii, binary;
    std::string embedded = single(ascii, dir, primitive(ascii.positions(kFive), -1, TINYGLTF_MODE_TRIANGLE_FAN), "e.gltf");
    std::vector<uint8_t> text = readBytes(embedded);
    CHECK(std::string(text.begin(), text.end()).find("data:application/octet-stream;base64,") != std::string::npos);
    CHECK(sameBits(readGltf(embedded),
                   readGltf(single(binary, dir, primitive(binary.positions(kFive), -1, TINYGLTF_MODE_TRIANGLE_FAN), "e.glb"))));
}

TEST_CASE("glTF: URIs are file names, never shell words or devices", "[stream][gltf]") {
    ScratchDir dir("gltf");
    std::string marker = dir.file("pwned");
    auto withUri = [&](const std::string& uri) {
        return fmt::format(R"({{
          "asset": {{"version": "2.0"}},
          "buffers": [{{"uri": "{}", "byteLength": 36}}],
          "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
          "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}}],
          "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
          "nodes": [{{"mesh": 0}}]
        }})", uri);
    };
    // URIs must never reach shell word expansion (tinygltf's default uses wordexp).
    writeText(dir.file("inject.gltf"), withUri("$(touch " + marker + ").bin"));
    CHECK_THROWS_AS(readGltf(dir.file("inject.gltf")), InputError);
    CHECK_FALSE(std::filesystem::exists(marker));
    // A device would never end (or never answer); only regular files are read.
    writeText(dir.file("device.gltf"), withUri("../../../../../../../../../../dev/zero"));
    CHECK_THROWS_AS(readGltf(dir.file("device.gltf")), InputError);
    std::filesystem::create_directory(dir.file("folder.bin"));
    writeText(dir.file("folder.gltf"), withUri("folder.bin"));
    CHECK_THROWS_AS(readGltf(dir.file("folder.gltf")), InputError);
    // Missing textures do not matter to geometry.
    std::vector<float> data = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    writeBytes(dir.file("tri.bin"), data.data(), data.size() * 4);
    std::string textured = withUri("tri.bin");
    textured.insert(textured.rfind('}'), R"(, "images": [{"uri": "missing.png"}])");
    writeText(dir.file("textured.gltf"), textured);
    CHECK(readGltf(dir.file("textured.gltf")).size() == 1);
}

TEST_CASE("glTF: validation names the file and the offending object", "[stream][gltf]") {
    ScratchDir dir("gltf");
    auto expectError = [&](ModelBuilder& b, const std::string& expected) {
        std::string path = b.save(dir, "bad.glb");
        CHECK(gltfError(path) == path + ": " + expected);
    };
    {
        ModelBuilder b;
        int view = b.view(kFive);  // 60 bytes
        b.accessor(view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, 6);
        expectError(b, "accessor 0 reads past the end of bufferView 0 (needs 72 bytes, has 60)");
    }
    {
        ModelBuilder b;
        int view = b.view(kFive);
        b.accessor(view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, 5, false, 4);
        expectError(b, "accessor 0 reads past the end of bufferView 0 (needs 64 bytes, has 60)");
    }
    {
        ModelBuilder b;
        b.view(kFive, 8);  // stride 8 < 12-byte VEC3
        b.accessor(0, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, 2);
        expectError(b, "accessor 0: bufferView 0 byteStride 8 is smaller than the 12-byte element");
    }
    {
        ModelBuilder b;
        b.view(kFive);
        b.accessor(0, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, size_t(1) << 62);
        expectError(b, "accessor 0 reads past the end of bufferView 0 (needs more than 2^64 bytes, has 60)");
    }
    {
        ModelBuilder b;
        b.view(kFive);
        b.model.bufferViews[0].byteLength = 1000;
        expectError(b, "bufferView 0 (bytes 0..+1000) lies outside buffer 0 (60 bytes)");
    }
    {
        ModelBuilder b;
        int pos = b.positions(kFive);
        single(b, dir, primitive(pos, b.indices(std::vector<uint16_t>{0, 1, 5})));
        expectError(b, "mesh 0 primitive 0: accessor 1 element 2 is index 5, but POSITION accessor 0 has 5 vertices");
    }
    {
        ModelBuilder b;
        int pos = b.positions(kFive);
        single(b, dir, primitive(pos, b.indices(std::vector<uint16_t>{0, 1, 2, 3})));
        expectError(b, "mesh 0 primitive 0: TRIANGLES primitive has 4 vertices, not a multiple of 3");
    }
    {
        ModelBuilder b;
        int pos = b.accessor(b.view(kFive), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, 6);
        single(b, dir, primitive(pos));
        expectError(b, "mesh 0 primitive 0: POSITION accessor 0 is not VEC3");
    }
    {
        // Checked as the file opens, for every command: a bake of a uniform MASK texture never
        // read the coordinates, while convert to glTF refused the same file.
        ModelBuilder b;
        tinygltf::Primitive p = primitive(b.positions(kFive));
        p.attributes["TEXCOORD_0"] = 0;  // the VEC3 positions
        single(b, dir, p);
        expectError(b, "mesh 0 primitive 0: TEXCOORD_0 accessor 0 is not VEC2");
    }
    {
        ModelBuilder b;
        tinygltf::Primitive p = primitive(b.positions(kFive));
        p.attributes["NORMAL"] = b.accessor(b.view(std::vector<float>(10, 0.5f)), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, 5);
        single(b, dir, p);
        expectError(b, "mesh 0 primitive 0: NORMAL accessor 1 is not VEC3");
    }
    {
        ModelBuilder b;
        int pos = b.positions(kFive);
        int idx = b.accessor(b.view(std::vector<float>{0, 1, 2}), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, 3);
        single(b, dir, primitive(pos, idx));
        expectError(b, "mesh 0 primitive 0: indices accessor 1 has componentType 5126 (must be an unsigned integer type)");
    }
    {
        ModelBuilder b;
        single(b, dir, primitive(b.positions(kFive), -1, TINYGLTF_MODE_TRIANGLE_STRIP));
        b.model.nodes[0].children = {0};  // a cycle
        expectError(b, "node 0 is reached twice (the node hierarchy must be a tree)");
    }
    {
        ModelBuilder b;
        int mesh = b.mesh({primitive(b.positions(kFive), -1, TINYGLTF_MODE_TRIANGLE_STRIP)});
        b.node(-1, {2});
        b.node(-1, {2});
        b.node(mesh);
        b.scene({0, 1});  // node 2 shared by two parents
        expectError(b, "node 2 is reached twice (the node hierarchy must be a tree)");
    }
    {
        ModelBuilder b;
        int pos = b.accessor(-1, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, size_t(1) << 60);
        single(b, dir, primitive(pos));
        expectError(b, "mesh 0 primitive 0: POSITION accessor 0 has no bufferView");
    }
    {
        ModelBuilder b;
        b.node(3);
        b.scene({0});
        expectError(b, "node 0 refers to mesh 3 (file has 0)");
    }
    {
        ModelBuilder b;
        b.node().rotation = {0, 0, 1};
        b.scene({0});
        expectError(b, "node 0 rotation has 3 values (needs 4)");
    }
    {
        ModelBuilder b;
        b.node().name = "empty";  // tinygltf cannot load a node without any property
        b.scene({0});
        b.model.defaultScene = 4;
        expectError(b, "default scene 4 does not exist (file has 1)");
    }
}

TEST_CASE("glTF: non-finite positions are input errors", "[stream][gltf]") {
    ScratchDir dir("gltf");
    std::vector<glm::vec3> points = kFive;
    points[4].y = std::numeric_limits<float>::quiet_NaN();
    ModelBuilder b;
    std::string path = single(b, dir, primitive(b.positions(points), -1, TINYGLTF_MODE_TRIANGLE_FAN));
    TriangleSourcePtr source = openGltf(path);  // positions are checked as triangles are read
    CHECK_THROWS_WITH(readAll(*source), path + ": mesh 0 primitive 0: POSITION accessor 0 element 4 is not finite");
}

TEST_CASE("glTF: the asset object and a 2.x version are required", "[stream][gltf]") {
    // Without them the blocker stream read the file while a vertex bake failed in tinygltf after
    // its cast, and a glTF 1.0 file read as 2.0.
    ScratchDir dir("gltf");
    const std::string rest = R"("scenes":[{"nodes":[]}],"nodes":[])";
    writeText(dir.file("none.gltf"), "{" + rest + "}");
    CHECK(gltfError(dir.file("none.gltf")) == dir.file("none.gltf") + ": has no \"asset\" object, which glTF 2.0 requires");
    writeText(dir.file("noversion.gltf"), R"({"asset":{},)" + rest + "}");
    CHECK(gltfError(dir.file("noversion.gltf")) == dir.file("noversion.gltf") + ": asset.version must be a string such as \"2.0\"");
    writeText(dir.file("v1.gltf"), R"({"asset":{"version":"1.0"},)" + rest + "}");
    CHECK(gltfError(dir.file("v1.gltf")) == dir.file("v1.gltf") + ": is glTF version \"1.0\"; penumbra reads glTF 2.x");
    writeText(dir.file("v21.gltf"), R"({"asset":{"version":"2.1"},)" + rest + "}");
    CHECK(gltfError(dir.file("v21.gltf")) == "no error");
}

TEST_CASE("glTF: load failures carry tinygltf's first error line", "[stream][gltf]") {
    ScratchDir dir("gltf");
    CHECK(gltfError(dir.file("missing.gltf")).rfind(dir.file("missing.gltf") + ": cannot open", 0) == 0);
    writeText(dir.file("junk.gltf"), "{ this is not json");
    std::string message = gltfError(dir.file("junk.gltf"));
    CHECK(message.rfind(dir.file("junk.gltf") + ": ", 0) == 0);
    CHECK(message.find('\n') == std::string::npos);
    // An empty file, or a .glb that is not one, is named so, not by the JSON parser's complaint.
    writeText(dir.file("empty.glb"), "");
    CHECK(gltfError(dir.file("empty.glb")) == dir.file("empty.glb") + ": is empty");
    writeText(dir.file("empty.gltf"), "");
    CHECK(gltfError(dir.file("empty.gltf")) == dir.file("empty.gltf") + ": is empty");
    writeText(dir.file("bad.glb"), "XXXX\x02\0\0\0{}");
    CHECK(gltfError(dir.file("bad.glb")) == dir.file("bad.glb") + ": is not a GLB file: it starts with \"XXXX\", not \"glTF\"");
    writeText(dir.file("short.glb"), "gl");
    CHECK(gltfError(dir.file("short.glb")) == dir.file("short.glb") + ": is not a GLB file: it starts with \"gl\", not \"glTF\"");
    CHECK(gltfError("/dev/zero") == "/dev/zero: not a regular file");
    CHECK(gltfError(dir.path.string()) == dir.path.string() + ": not a regular file");
}

TEST_CASE("glTF: sample models", "[stream][gltf][data]") {
    for (const char* name : {"Cube/Cube.gltf", "box01.glb"}) {
        INFO(name);
        TriangleSourcePtr source = openGltf(sharedData("gltf/") + name);
        CHECK(source->sizeHint() == 12u);
        auto tris = readAll(*source);
        CHECK(tris.size() == 12);
        for (const Triangle& t : tris) CHECK(t.area() > 0);
    }
}

TEST_CASE("glTF: tinygltf's malformed samples fail cleanly", "[stream][gltf][data][robustness]") {
    for (const char* name : {"integer-out-of-bounds.gltf", "invalid-buffer-index.gltf",
                             "invalid-buffer-view-index.gltf", "invalid-primitive-indices.gltf"}) {
        INFO(name);
        CHECK_THROWS_AS(readGltf(sharedData("gltf/BoundsChecking/") + name), InputError);
    }
    // Loadable or not, it must not crash.
    try {
        readGltf(sharedData("gltf/regression/zero-sized-bin-chunk-issue-440.glb"));
    } catch (const InputError&) {
    }
}

TEST_CASE("glTF: every truncated prefix and damaged byte of a .glb fails cleanly", "[stream][gltf][robustness]") {
    ScratchDir dir("gltf");
    ModelBuilder b;
    int pos = b.positions(kFive);
    std::string path = single(b, dir, primitive(pos, b.indices(std::vector<uint16_t>{0, 1, 2, 2, 1, 3})), "src.glb");
    const std::vector<uint8_t> good = readBytes(path);
    REQUIRE(readGltf(path).size() == 2);

    std::string cut = dir.file("cut.glb");
    for (size_t length = 0; length < good.size(); ++length) {
        writeBytes(cut, good.data(), length);
        INFO("prefix of " << length << " bytes");
        CHECK_THROWS_AS(readGltf(cut), InputError);
    }
    // Damage may leave a loadable file (a changed coordinate); anything but a crash is fine.
    for (size_t i = 0; i < good.size(); ++i) {
        std::vector<uint8_t> bytes = good;
        bytes[i] ^= 0xFF;
        writeBytes(cut, bytes);
        try {
            for (const Triangle& t : readGltf(cut)) CHECK(isFinite(t));
        } catch (const InputError&) {
        }
    }
}
