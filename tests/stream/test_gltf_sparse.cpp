// Tests for sparse glTF accessors (glTF 2.0, "Sparse Accessors"): substitutions over a
// bufferView and over zeros, for positions, indices and attributes, and the file errors that
// name the accessor.

#include "stream/util/Error.h"
#include "stream/GltfBytes.h"
#include "stream/GltfDocument.h"
#include "stream/GltfPrimitive.h"
#include "stream/GltfReader.h"
#include "GltfModelBuilder.h"

#include <catch2/catch.hpp>

#include <functional>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// Makes accessor @p a sparse: elements @p at take @p values (one VEC3 each, or the raw bytes).
void makeSparse(ModelBuilder& b, int a, const std::vector<uint16_t>& at, const std::vector<glm::vec3>& values) {
    tinygltf::Accessor& acc = b.model.accessors[size_t(a)];
    acc.sparse.isSparse = true;
    acc.sparse.count = int(at.size());
    acc.sparse.indices.bufferView = b.view(at);
    acc.sparse.indices.byteOffset = 0;
    acc.sparse.indices.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
    acc.sparse.values.bufferView = b.view(values);
    acc.sparse.values.byteOffset = 0;
}

std::string readError(const std::string& path) {
    try {
        readAll(*openGltf(path));
    } catch (const InputError& e) {
        return e.what();
    }
    return "no error";
}

}  // namespace

TEST_CASE("glTF sparse: substitutions over a bufferView replace those positions only", "[stream][gltf]") {
    ScratchDir dir("gltf-sparse");
    const std::vector<glm::vec3> base = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}, {3, 0, 0}, {2, 1, 0}};
    ModelBuilder b;
    const int pos = b.positions(base);
    makeSparse(b, pos, {1, 5}, {{7, 0, 0}, {2, 9, 0}});
    const std::vector<Triangle> tris = readAll(*openGltf(single(b, dir, primitive(pos))));
    REQUIRE(tris.size() == 2);
    CHECK(tris[0].v[0] == glm::vec3(0, 0, 0));
    CHECK(tris[0].v[1] == glm::vec3(7, 0, 0));
    CHECK(tris[0].v[2] == glm::vec3(0, 1, 0));
    CHECK(tris[1].v[0] == glm::vec3(2, 0, 0));
    CHECK(tris[1].v[1] == glm::vec3(3, 0, 0));
    CHECK(tris[1].v[2] == glm::vec3(2, 9, 0));
}

TEST_CASE("glTF sparse: without a bufferView the other elements are zero, read in any order", "[stream][gltf]") {
    ScratchDir dir("gltf-sparse");
    ModelBuilder b;
    const int pos = b.accessor(-1, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, 5);
    makeSparse(b, pos, {1, 2, 4}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}});
    // Indices jump back and forth, so the look-up cannot rely on reads in order.
    const int idx = b.indices(std::vector<uint8_t>{4, 2, 1, 0, 1, 2, 3, 4, 2});
    const std::vector<Triangle> tris = readAll(*openGltf(single(b, dir, primitive(pos, idx))));
    REQUIRE(tris.size() == 3);
    CHECK(tris[0].v[0] == glm::vec3(0, 0, 1));
    CHECK(tris[0].v[1] == glm::vec3(0, 1, 0));
    CHECK(tris[0].v[2] == glm::vec3(1, 0, 0));
    CHECK(tris[1].v[0] == glm::vec3(0, 0, 0));
    CHECK(tris[2].v[0] == glm::vec3(0, 0, 0));  // element 3: not substituted
    CHECK(tris[2].v[1] == glm::vec3(0, 0, 1));
}

TEST_CASE("glTF sparse: indices and attributes read through their substitutions", "[stream][gltf]") {
    ScratchDir dir("gltf-sparse");
    ModelBuilder b;
    const int pos = b.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {5, 5, 5}});
    const int idx = b.indices(std::vector<uint16_t>{0, 1, 0});
    tinygltf::Accessor& acc = b.model.accessors[size_t(idx)];
    acc.sparse.isSparse = true, acc.sparse.count = 1;
    acc.sparse.indices.bufferView = b.view(std::vector<uint32_t>{2}), acc.sparse.indices.byteOffset = 0;
    acc.sparse.indices.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    acc.sparse.values.bufferView = b.view(std::vector<uint16_t>{2}), acc.sparse.values.byteOffset = 0;
    tinygltf::Primitive prim = primitive(pos, idx);
    const int normals = b.positions({{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}});
    makeSparse(b, normals, {3}, {{1, 0, 0}});
    prim.attributes["NORMAL"] = normals;
    const std::string path = single(b, dir, prim);

    const std::vector<Triangle> tris = readAll(*openGltf(path));
    REQUIRE(tris.size() == 1);
    CHECK(tris[0].v[2] == glm::vec3(0, 1, 0));  // index 0 replaced by 2
    const GltfDocument doc = loadGltfDocument(path);
    GltfBytes bytes(doc, 0);
    const auto layout = gltfTrianglePrimitive(doc, 0, 0);
    REQUIRE(layout);
    CHECK(layout->decodeBytes == 2 * sizeof(uint32_t));  // the two sparse index lists stay resident
    CHECK_FALSE(layout->compressed());  // so a vertex bake can write its copy
    GltfPrimitiveReader reader(doc, bytes, *layout);
    CHECK(reader.attribute("NORMAL", 3, 2) == glm::vec4(0, 0, 1, 0));
    CHECK(reader.attribute("NORMAL", 3, 3) == glm::vec4(1, 0, 0, 0));
}

TEST_CASE("glTF sparse: malformed storage names the accessor", "[stream][gltf]") {
    ScratchDir dir("gltf-sparse");
    const std::vector<glm::vec3> tri = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    auto errorOf = [&](const std::function<void(ModelBuilder&, int)>& damage) {
        ModelBuilder b;
        const int pos = b.positions(tri);
        makeSparse(b, pos, {0, 2}, {{1, 1, 1}, {2, 2, 2}});
        damage(b, pos);
        return readError(single(b, dir, primitive(pos)));
    };
    CHECK_THAT(errorOf([](ModelBuilder&, int) {}), Catch::Equals("no error"));
    CHECK_THAT(errorOf([](ModelBuilder& b, int a) { b.model.accessors[size_t(a)].sparse.count = 4; }),
               Catch::EndsWith("accessor 0 sparse count 4 must be in 1..3 (the accessor's count)"));
    CHECK_THAT(errorOf([](ModelBuilder& b, int a) { b.model.accessors[size_t(a)].sparse.count = 0; }),
               Catch::EndsWith("accessor 0 sparse count 0 must be in 1..3 (the accessor's count)"));
    CHECK_THAT(errorOf([](ModelBuilder& b, int a) {
                   auto& acc = b.model.accessors[size_t(a)];
                   acc.sparse.indices.bufferView = b.view(std::vector<uint16_t>{2, 1});
               }),
               Catch::EndsWith("accessor 0 sparse index 1 is 1, not above the one before (2): sparse indices must increase"));
    CHECK_THAT(errorOf([](ModelBuilder& b, int a) {
                   b.model.accessors[size_t(a)].sparse.indices.bufferView = b.view(std::vector<uint16_t>{0, 3});
               }),
               Catch::EndsWith("accessor 0 sparse index 1 is 3, but the accessor has 3 elements"));
    CHECK_THAT(errorOf([](ModelBuilder& b, int a) {
                   b.model.accessors[size_t(a)].sparse.values.bufferView = b.view(std::vector<glm::vec3>{{1, 1, 1}});
               }),
               Catch::EndsWith("accessor 0 sparse values reads past the end of bufferView 3 (needs 24 bytes, has 12)"));
    CHECK_THAT(errorOf([](ModelBuilder& b, int a) { b.model.accessors[size_t(a)].sparse.indices.componentType = 5126; }),
               Catch::EndsWith("accessor 0 sparse indices componentType 5126 must be an unsigned integer type"));
    CHECK_THAT(errorOf([](ModelBuilder& b, int a) { b.model.accessors[size_t(a)].sparse.indices.bufferView = 9; }),
               Catch::EndsWith("accessor 0 sparse indices refers to bufferView 9 (file has 3)"));
    CHECK_THAT(errorOf([](ModelBuilder& b, int a) {
                   b.model.bufferViews[size_t(b.model.accessors[size_t(a)].sparse.values.bufferView)].byteStride = 16;
               }),
               Catch::EndsWith("accessor 0 sparse values: bufferView 2 has byteStride 16, but sparse arrays are tightly packed (12 bytes)"));
}

TEST_CASE("glTF sparse: every truncated prefix and damaged byte fails cleanly", "[stream][gltf][robustness]") {
    ScratchDir dir("gltf-sparse");
    ModelBuilder b;
    const int pos = b.accessor(-1, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, 4);
    makeSparse(b, pos, {0, 1, 3}, {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
    const std::string path = single(b, dir, primitive(pos, b.indices(std::vector<uint16_t>{0, 1, 3, 3, 1, 2})), "src.glb");
    const std::vector<uint8_t> good = readBytes(path);
    REQUIRE(readAll(*openGltf(path)).size() == 2);
    const std::string cut = dir.file("cut.glb");
    for (size_t length = 0; length < good.size(); ++length) {
        writeBytes(cut, good.data(), length);
        INFO("prefix of " << length << " bytes");
        CHECK(readError(cut) != "no error");
    }
    for (size_t i = 0; i < good.size(); ++i) {  // damage may leave a loadable file; never a crash
        std::vector<uint8_t> bytes = good;
        bytes[i] ^= 0xFF;
        writeBytes(cut, bytes);
        try {
            for (const Triangle& t : readAll(*openGltf(cut))) CHECK(isFinite(t));
        } catch (const InputError&) {
        }
    }
}
