// Tests for glTF output in bounded memory (GltfStreamWriter.h, GltfConvert.h): a mesh larger than
// the writer's open bytes is split into primitives and reads back as the same triangles, with
// the same normals and texture coordinates, as the whole-mesh loader gives; OBJ groups that
// interleave stay one mesh each; a malformed file writes nothing.

#include "stream/GeometryFile.h"
#include "stream/GltfConvert.h"
#include "stream/GltfStreamWriter.h"
#include "stream/IndexedMesh.h"
#include "stream/ObjTokenizer.h"
#include "stream/util/Error.h"
#include "GltfValidator.h"
#include "StreamTestFiles.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <random>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// A w x h sheet of quads, two triangles each, sharing their corners.
std::vector<Triangle> sheet(int w, int h) {
    std::vector<Triangle> tris;
    for (int z = 0; z < h; ++z)
        for (int x = 0; x < w; ++x) {
            auto at = [](int i, int k) { return glm::vec3(float(i), 0.01f * float(i * k), float(k)); };
            const glm::vec3 a = at(x, z), b = at(x + 1, z), c = at(x + 1, z + 1), d = at(x, z + 1);
            tris.push_back(tri(a, c, b));
            tris.push_back(tri(a, d, c));
        }
    return tris;
}

/// Each triangle's corners as the meshes give them: position, normal and uv0 per corner.
struct Corner {
    glm::vec3 position, normal;
    glm::vec2 uv;
};
std::vector<std::vector<Corner>> cornersOf(const std::vector<IndexedMesh>& meshes) {
    std::vector<std::vector<Corner>> out;
    for (const IndexedMesh& m : meshes) {
        std::vector<Corner>& list = out.emplace_back();
        for (uint32_t i : m.indices)
            list.push_back({m.position[i], m.normal.empty() ? glm::vec3(9) : m.normal[i], m.uv0.empty() ? glm::vec2(9) : m.uv0[i]});
    }
    return out;
}

/// @p a and @p b hold the same meshes, names, triangles and attributes (normals to float
/// roundoff: the reader normalizes them again).
void checkSameMeshes(const std::vector<IndexedMesh>& a, const std::vector<IndexedMesh>& b) {
    REQUIRE(a.size() == b.size());
    const auto ca = cornersOf(a), cb = cornersOf(b);
    for (size_t m = 0; m < a.size(); ++m) {
        INFO("mesh " << m << " " << a[m].name);
        CHECK(a[m].name == b[m].name);
        CHECK(a[m].normal.empty() == b[m].normal.empty());
        CHECK(a[m].uv0.empty() == b[m].uv0.empty());
        REQUIRE(ca[m].size() == cb[m].size());
        size_t bad = 0;
        for (size_t k = 0; k < ca[m].size(); ++k)
            bad += ca[m][k].position != cb[m][k].position || ca[m][k].uv != cb[m][k].uv ||
                   glm::length(ca[m][k].normal - cb[m][k].normal) > 1e-6f;
        CHECK(bad == 0);
    }
}

std::vector<Triangle> sorted(std::vector<Triangle> tris) {
    std::sort(tris.begin(), tris.end(), [](const Triangle& a, const Triangle& b) { return std::memcmp(&a, &b, sizeof a) < 0; });
    return tris;
}

}  // namespace

TEST_CASE("GltfStreamWriter: a mesh past its open bytes is split into primitives of the same triangles", "[stream][gltf]") {
    ScratchDir dir("gltf-stream");
    const std::vector<Triangle> tris = sheet(60, 40);
    std::string validator;
    const bool validate = validatorAvailable(validator);
    for (const auto indexing : {GltfStreamWriter::Indexing::Welded, GltfStreamWriter::Indexing::None})
        for (const char* name : {"s.glb", "s.gltf"}) {
            INFO(name << (indexing == GltfStreamWriter::Indexing::None ? " soup" : " welded"));
            GltfStreamWriter out(dir.file(name), std::string(name) == "s.glb", 16 << 10);
            VectorSource source(tris);
            addTrianglesOf(source, out, "sheet", indexing);
            out.commit();
            CHECK(out.primitiveCount() > 5);
            if (validate) {  // the Khronos validator accepts the split file
                std::string log;
                CHECK(validateGltf(dir.file(name), validator, log) == 0);
                INFO(log);
                CHECK(log.find(" 0 errors, 0 warnings") != std::string::npos);
            }
            CHECK(sameBits(readAll(*openGeometryFile(dir.file(name))), tris));
            const std::vector<IndexedMesh> meshes = loadIndexedMeshes(dir.file(name), glm::mat4(1.0f));
            REQUIRE(meshes.size() == 1);  // the primitives of one mesh
            CHECK(meshes[0].name == "sheet");
            // Welded: each primitive shares its corners, so far fewer vertices than corners.
            if (indexing == GltfStreamWriter::Indexing::Welded) CHECK(meshes[0].position.size() < tris.size());
            else CHECK(meshes[0].position.size() == 3 * tris.size());
        }
    // With room for the whole mesh: one primitive, every shared corner welded once.
    GltfStreamWriter whole(dir.file("w.glb"), true);
    VectorSource source(tris);
    addTrianglesOf(source, whole, "sheet", GltfStreamWriter::Indexing::Welded);
    whole.commit();
    CHECK(whole.primitiveCount() == 1);
    CHECK(loadIndexedMeshes(dir.file("w.glb"), glm::mat4(1.0f))[0].position.size() == 61 * 41);
}

TEST_CASE("convert to glTF in pieces gives the meshes the whole-mesh loader gives", "[stream][gltf][data]") {
    ScratchDir dir("gltf-stream");
    // Interleaved groups with normals and texture coordinates, a group without normals, a
    // polygon, and a real mesh with texture coordinates and a real glTF with both attributes.
    writeText(dir.file("g.obj"), "v 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\nv 3 0 0\nv 4 0 0\nv 3 1 0\n"
                                 "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 2 0\nvn 0 0 1\n"
                                 "g a\nf 1/1/1 2/2/1 3/3/1\ng b\nf 5/1/2 6/2/2 7/3/2\ng a\nf 1/1/1 3/3/1 4/4/1\n"
                                 "g c\nf 1/1 2/2 3/3 4/4\n");
    for (const std::string& input : {dir.file("g.obj"), sharedData("meshes/spot.obj"), sharedData("gltf/Cube/Cube.gltf")}) {
        for (const uint64_t open : {uint64_t(1) << 10, GltfStreamWriter::kOpenBytes}) {
            INFO(input << " open bytes " << open);
            GltfStreamWriter out(dir.file("o.glb"), true, open);
            addMeshesOfFile(input, out);
            out.commit();
            checkSameMeshes(loadIndexedMeshes(input, glm::mat4(1.0f)), loadIndexedMeshes(dir.file("o.glb"), glm::mat4(1.0f)));
            // The same triangles; an interleaved group's come together, so compare them sorted.
            CHECK(sameBits(sorted(readAll(*openGeometryFile(dir.file("o.glb")))), sorted(readAll(*openGeometryFile(input)))));
        }
    }
    convertGeometryFile(dir.file("g.obj"), dir.file("g.glb"));
    const std::vector<IndexedMesh> groups = loadIndexedMeshes(dir.file("g.glb"), glm::mat4(1.0f));
    REQUIRE(groups.size() == 3);
    CHECK(groups[0].name == "a");
    CHECK(groups[0].position.size() == 4);  // the interleaved group's quad, welded
    CHECK(groups[0].normal[0] == glm::vec3(0, 1, 0));
    CHECK(groups[2].normal.empty());
    CHECK(groups[2].uv0.size() == 4);
}

TEST_CASE("convert to glTF: a malformed OBJ writes nothing, even past the open bytes", "[stream][gltf]") {
    ScratchDir dir("gltf-stream");
    std::string text;
    for (int i = 0; i < 20000; ++i) text += fmt::format("v {} 0 0\nv {} 1 0\nv {} 0 1\nf -3 -2 -1\n", i, i, i);
    writeText(dir.file("bad.obj"), text + "f 1 2 70000\n");
    CHECK_THROWS_WITH(convertGeometryFile(dir.file("bad.obj"), dir.file("bad.glb")),
                      Catch::Contains("bad.obj:80001") && Catch::Contains("70000"));
    CHECK(dir.entries() == std::vector<std::string>{"bad.obj"});
}

TEST_CASE("ObjGroupIndex: a part per name, part 0 before any group, a bare g a part of its own", "[stream][obj]") {
    ObjGroupIndex groups;
    CHECK(groups.size() == 1);
    CHECK(groups.select("a") == 1);
    CHECK(groups.select("") == 2);  // a bare `g` is not part 0 (the faces before any group)
    CHECK(groups.select("b") == 3);
    CHECK(groups.select("a") == 1);
    CHECK(groups.select("") == 2);
    CHECK(groups.size() == 4);
}

TEST_CASE("convert to glTF: an OBJ of many groups gives a mesh per group, in order", "[stream][gltf]") {
    ScratchDir dir("gltf-stream");
    std::string text;
    for (int i = 0; i < 5000; ++i)
        text += fmt::format("g part{}\nv {} 0 0\nv {} 1 0\nv {} 0 1\nf -3 -2 -1\n", i % 2500, i, i, i);
    writeText(dir.file("many.obj"), text);
    convertGeometryFile(dir.file("many.obj"), dir.file("many.glb"));
    const std::vector<IndexedMesh> meshes = loadIndexedMeshes(dir.file("many.glb"), glm::mat4(1.0f));
    REQUIRE(meshes.size() == 2500);  // each name comes back once: its two triangles are one mesh
    CHECK(meshes[7].name == "part7");
    CHECK(meshes[7].indices.size() == 6);
    CHECK(meshes[7].position[3] == glm::vec3(2507, 0, 0));
}

TEST_CASE("convert to glTF: a group name that is not UTF-8 is written with U+FFFD in its place", "[stream][gltf]") {
    // Old exporters write Latin-1 names; the JSON library's own error ended the convert.
    ScratchDir dir("gltf-stream-latin1");
    writeText(dir.file("latin1.obj"), "o caf\xe9\nv 0 1 0\nv 1 1 0\nv 0 1 1\nf 1 2 3\ng chair\nv 0 2 0\nv 1 2 0\nv 0 2 1\nf 4 5 6\n");
    convertGeometryFile(dir.file("latin1.obj"), dir.file("latin1.glb"));
    const std::vector<IndexedMesh> meshes = loadIndexedMeshes(dir.file("latin1.glb"), glm::mat4(1.0f));
    REQUIRE(meshes.size() == 2);
    CHECK(meshes[0].name == "caf\xef\xbf\xbd");
    CHECK(meshes[1].name == "chair");
}

namespace {

/// A source that says it holds more triangles than a glTF buffer takes, and must not be read.
class HugeSource final : public TriangleSource {
public:
    size_t read(std::span<Triangle>) override { fail("huge", "read although the count was known to be too large"); }
    void rewind() override {}
    std::string name() const override { return "huge"; }
    std::optional<uint64_t> sizeHint() const override { return 200'000'000; }
};

}  // namespace

TEST_CASE("convert to glTF: what is known before the work is refused before it", "[stream][gltf]") {
    ScratchDir dir("gltf-stream");
    // 200M triangles of 36 bytes: past a GLB's 4 GiB, known from the count.
    HugeSource huge;
    CHECK_THROWS_WITH(convertGeometry(huge, dir.file("h.glb")), Catch::Contains("200000000 triangles do not fit in one glTF buffer"));
    // A folder where a .gltf's buffer file would go.
    writeText(dir.file("q.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    std::filesystem::create_directory(dir.file("q.bin"));
    CHECK_THROWS_WITH(GltfStreamWriter(dir.file("q.gltf"), false), Catch::Contains("q.bin"));
    CHECK(dir.entries() == std::vector<std::string>{"q.bin", "q.obj"});
}
