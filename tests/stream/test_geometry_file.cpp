// Tests for opening geometry by extension, scanning sources, and converting between formats
// (bit-exact round trips through OBJ, glTF and .ptri; atomic, all-or-nothing output).

#include "stream/util/Error.h"
#include "stream/GeometryFile.h"
#include "stream/IndexedMesh.h"
#include "stream/ObjReader.h"
#include "stream/PtriFormat.h"
#include "StreamTestFiles.h"

#include <catch2/catch.hpp>

#include <cfloat>
#include <chrono>
#include <filesystem>
#include <cmath>
#include <random>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// Triangles whose coordinates exercise float printing and parsing: tiny, huge, denormal,
/// negative zero, values without short decimal forms.
std::vector<Triangle> awkwardTriangles() {
    std::vector<Triangle> tris;
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::uniform_int_distribution<int> exponent(-40, 38);
    for (int i = 0; i < 300; ++i) {
        Triangle t;
        for (auto& p : t.v)
            for (int k = 0; k < 3; ++k) p[k] = unit(rng) * std::pow(10.0f, float(exponent(rng)));
        tris.push_back(t);
    }
    tris.push_back(tri({-0.0f, 0.1f, 1.0f / 3.0f}, {FLT_MAX, -FLT_MAX, FLT_MIN}, {1e-45f, -1e-45f, 16777217.0f}));
    tris.push_back(tri({0.3f, 123456.789f, -2.5e-20f}, {1, 2, 3}, {7e37f, -6e-38f, 0.2f}));
    return tris;
}

/// A source that fails after its first chunk, like a reader hitting a damaged region.
class FailingSource final : public TriangleSource {
public:
    size_t read(std::span<Triangle> out) override {
        if (calls_++ > 0) fail("failing", "simulated read error");
        out[0] = tri({0, 0, 0}, {1, 0, 0}, {0, 1, 0});
        return 1;
    }
    void rewind() override { calls_ = 0; }
    std::string name() const override { return "failing"; }

private:
    int calls_ = 0;
};

}  // namespace

TEST_CASE("GeometryFile: readers are chosen by extension, case-insensitively", "[stream][geometry]") {
    ScratchDir dir("geometry");
    std::vector<Triangle> tris = {tri({0, 0, 0}, {1, 0, 0}, {0, 1, 0})};
    VectorSource source(tris);
    for (const char* name : {"a.obj", "b.OBJ", "c.ptri", "d.PTri", "e.glb", "f.GLB", "g.gltf", "h.glTF"}) {
        INFO(name);
        convertGeometry(source, dir.file(name));
        TriangleSourcePtr opened = openGeometryFile(dir.file(name));
        CHECK(sameBits(readAll(*opened), tris));
    }
    // Content decides between glTF's two encodings, so a misnamed file still loads.
    std::filesystem::copy_file(dir.file("e.glb"), dir.file("binary.gltf"));
    CHECK(readAll(*openGeometryFile(dir.file("binary.gltf"))).size() == 1);

    CHECK_THROWS_WITH(openGeometryFile(dir.file("x.stl")),
                      dir.file("x.stl") + ": unknown geometry file extension '.stl' (expected .obj, .gltf, .glb or .ptri)");
    CHECK_THROWS_AS(openGeometryFile(dir.file("noextension")), InputError);
    CHECK_THROWS_AS(openGeometryFile(dir.file("missing.obj")), InputError);
    CHECK_THROWS_WITH(convertGeometry(source, dir.file("out.fbx")),
                      dir.file("out.fbx") + ": unknown output extension '.fbx' (expected .obj, .gltf, .glb or .ptri)");
}

TEST_CASE("GeometryFile: scanGeometry counts, bounds and measures, then rewinds", "[stream][geometry]") {
    std::vector<Triangle> tris = {tri({0, 0, 0}, {2, 0, 0}, {0, 2, 0}), tri({-1, 5, 3}, {-1, 6, 3}, {-1, 5, 4})};
    VectorSource source(tris);
    source.read(std::span<Triangle>(tris.data(), 1));  // scan must not depend on the read position
    GeometryInfo info = scanGeometry(source);
    CHECK(info.triangles == 2u);
    CHECK(info.lo == glm::vec3(-1, 0, 0));
    CHECK(info.hi == glm::vec3(2, 6, 4));
    CHECK(info.area == Approx(2.5));
    CHECK(readAll(source).size() == 2);

    VectorSource empty({});
    GeometryInfo none = scanGeometry(empty);
    CHECK(none.triangles == 0u);
    CHECK(none.lo == glm::vec3(0));
    CHECK(none.hi == glm::vec3(0));
    CHECK(none.area == 0.0);
}

TEST_CASE("GeometryFile: OBJ, glTF and .ptri carry identical triangles", "[stream][geometry]") {
    ScratchDir dir("geometry");
    const std::vector<Triangle> tris = awkwardTriangles();
    VectorSource source(tris);
    for (const char* name : {"x.ptri", "x.obj", "x.glb", "x.gltf"}) {
        INFO(name);
        convertGeometry(source, dir.file(name));
        TriangleSourcePtr back = openGeometryFile(dir.file(name));
        CHECK(back->sizeHint() == tris.size());
        CHECK(sameBits(readAll(*back), tris));
    }
    // And chained: OBJ -> glb -> ptri -> OBJ changes nothing.
    auto obj = openGeometryFile(dir.file("x.obj"));
    convertGeometry(*obj, dir.file("y.glb"));
    auto glb = openGeometryFile(dir.file("y.glb"));
    convertGeometry(*glb, dir.file("y.ptri"));
    auto ptri = openGeometryFile(dir.file("y.ptri"));
    convertGeometry(*ptri, dir.file("y.obj"));
    CHECK(sameBits(readAll(*openGeometryFile(dir.file("y.obj"))), tris));
}

TEST_CASE("GeometryFile: a real mesh converts bit-exactly to every format", "[stream][geometry][data]") {
    ScratchDir dir("geometry");
    TriangleSourcePtr spot = openObj(sharedData("meshes/spot.obj"));
    const std::vector<Triangle> tris = readAll(*spot);
    REQUIRE(tris.size() == 5856);
    for (const char* name : {"spot.ptri", "spot.glb", "spot.obj"}) {
        INFO(name);
        convertGeometry(*spot, dir.file(name));  // converting rewinds the source first
        CHECK(sameBits(readAll(*openGeometryFile(dir.file(name))), tris));
    }
    GeometryInfo a = scanGeometry(*spot), b = scanGeometry(*openGeometryFile(dir.file("spot.ptri")));
    CHECK(a.triangles == b.triangles);
    CHECK(a.lo == b.lo);
    CHECK(a.hi == b.hi);
    CHECK(a.area == b.area);
    PtriInfo header = readPtriHeader(dir.file("spot.ptri"));
    CHECK(header.lo == a.lo);
    CHECK(header.hi == a.hi);
}

TEST_CASE("GeometryFile: flags survive only in .ptri", "[stream][geometry]") {
    ScratchDir dir("geometry");
    VectorSource source({tri({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, kTriangleAlphaMatte)});
    convertGeometry(source, dir.file("f.ptri"));
    convertGeometry(source, dir.file("f.obj"));
    CHECK(readAll(*openGeometryFile(dir.file("f.ptri")))[0].flags == kTriangleAlphaMatte);
    CHECK(readAll(*openGeometryFile(dir.file("f.obj")))[0].flags == 0u);
}

TEST_CASE("GeometryFile: empty sources convert to empty files", "[stream][geometry]") {
    ScratchDir dir("geometry");
    VectorSource empty({});
    for (const char* name : {"e.ptri", "e.obj", "e.glb", "e.gltf"}) {
        INFO(name);
        convertGeometry(empty, dir.file(name));
        TriangleSourcePtr back = openGeometryFile(dir.file(name));
        CHECK(back->sizeHint() == 0u);
        CHECK(readAll(*back).empty());
    }
}

TEST_CASE("GeometryFile: a failed conversion leaves no output behind", "[stream][geometry]") {
    ScratchDir dir("geometry");
    for (const char* name : {"o.ptri", "o.obj", "o.glb", "o.gltf"}) {
        INFO(name);
        writeText(dir.file(name), "old");
        FailingSource failing;
        CHECK_THROWS_WITH(convertGeometry(failing, dir.file(name)), "failing: simulated read error");
        CHECK(dir.entries() == std::vector<std::string>{name});
        CHECK(readBytes(dir.file(name)).size() == 3);  // the previous file is untouched
        std::filesystem::remove(dir.file(name));
    }
    VectorSource one({tri({0, 0, 0}, {1, 0, 0}, {0, 1, 0})});
    CHECK_THROWS_AS(convertGeometry(one, dir.file("missing-dir/o.obj")), InputError);
    CHECK(dir.entries().empty());
}

TEST_CASE("convert to glTF welds shared corners and keeps normals and texture coordinates and groups", "[stream][gltf]") {
    ScratchDir dir("convert-weld");
    // Two groups; the quad's two triangles share two corners (same v/vt/vn), the triangle's
    // corners are all its own.
    writeText(dir.file("m.obj"), "v 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\nv 3 0 0\nv 4 0 0\nv 3 1 0\n"
                                 "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 1 0\nvn 0 0 1\n"
                                 "o quad\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\no tri\nf 5/1/2 6/2/2 7/3/2\n");
    for (const char* name : {"m.glb", "m.gltf"}) {
        INFO(name);
        convertGeometryFile(dir.file("m.obj"), dir.file(name));
        std::vector<IndexedMesh> meshes = loadIndexedMeshes(dir.file(name), glm::mat4(1.0f));
        REQUIRE(meshes.size() == 2);
        CHECK(meshes[0].name == "quad");
        CHECK(meshes[0].position.size() == 4);  // welded: 6 corners, 4 vertices
        CHECK(meshes[0].indices.size() == 6);
        REQUIRE(meshes[0].normal.size() == 4);
        CHECK(meshes[0].normal[0] == glm::vec3(0, 1, 0));
        REQUIRE(meshes[0].uv0.size() == 4);
        CHECK(meshes[0].uv0[2] == glm::vec2(1, 0));  // OBJ's (1, 1), v flipped to glTF's top-left origin
        CHECK(meshes[1].position.size() == 3);
        CHECK(meshes[1].normal[0] == glm::vec3(0, 0, 1));
        // The same triangles, bit for bit and in order, as the blocker stream reads them.
        CHECK(sameBits(readAll(*openGeometryFile(dir.file(name))), readAll(*openGeometryFile(dir.file("m.obj")))));
    }
}

TEST_CASE("convert from a triangle stream to glTF shares corners with identical positions", "[stream][gltf]") {
    ScratchDir dir("convert-stream");
    writeText(dir.file("q.obj"), "v 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\nf 1 2 3\nf 1 3 4\n");
    convertGeometry(*openGeometryFile(dir.file("q.obj")), dir.file("q.ptri"));
    convertGeometryFile(dir.file("q.ptri"), dir.file("q.glb"));
    std::vector<IndexedMesh> meshes = loadIndexedMeshes(dir.file("q.glb"), glm::mat4(1.0f));
    REQUIRE(meshes.size() == 1);
    CHECK(meshes[0].position.size() == 4);
    CHECK(sameBits(readAll(*openGeometryFile(dir.file("q.glb"))), readAll(*openGeometryFile(dir.file("q.obj")))));
}

TEST_CASE("GeometryFile: a .gltf too large for a data URI keeps its buffer in a .bin beside it", "[stream][gltf]") {
    // The writer embedded any size, the readers refuse data URIs above kMaxDataUriBytes: every
    // .gltf export above about 466,000 triangles could not be read back.
    ScratchDir dir("geometry");
    std::vector<Triangle> tris;
    const size_t count = kMaxDataUriBytes / 36 + 1000;
    for (size_t i = 0; i < count; ++i) {
        const float x = float(i % 1000), z = float(i / 1000);
        tris.push_back(tri({x, 0, z}, {x + 1, 0, z}, {x, 0.5f, z + 1}));
    }
    VectorSource source(tris);
    convertGeometry(source, dir.file("big.gltf"));
    CHECK(dir.entries() == std::vector<std::string>{"big.bin", "big.gltf"});
    CHECK(std::filesystem::file_size(dir.file("big.bin")) == 36 * count);
    CHECK(readBytes(dir.file("big.gltf")).size() < 4096);
    TriangleSourcePtr back = openGeometryFile(dir.file("big.gltf"));
    CHECK(back->sizeHint() == count);
    CHECK(sameBits(readAll(*back), tris));
    // A small one stays one file.
    VectorSource small({tri({0, 0, 0}, {1, 0, 0}, {0, 1, 0})});
    convertGeometry(small, dir.file("small.gltf"));
    CHECK_FALSE(std::filesystem::exists(dir.file("small.bin")));
}

TEST_CASE("GeometryFile: a file replaced or rewritten between two passes is an error, not another mesh", "[stream][geometry]") {
    // A bake reads its files once per pass: a .ptri renamed over, or a .glb or .bin rewritten at
    // the same size between the scan and the bucket pass, gave receivers of one version and
    // shadows of another, exit 0.
    ScratchDir dir("geometry-changed");
    std::vector<Triangle> first = awkwardTriangles(), second = first;
    std::swap(second.front(), second.back());  // the same count and size, other triangles
    for (const char* name : {"x.ptri", "x.glb", "x.gltf", "x.obj"})
        for (const bool rename : {true, false}) {
            INFO(name << (rename ? ": renamed over" : ": rewritten in place"));
            const std::string path = dir.file(name), other = dir.file(std::string("other-") + name);
            VectorSource a(first), b(second);
            convertGeometry(a, path);
            convertGeometry(b, other);
            TriangleSourcePtr source = openGeometryFile(path);
            CHECK(sameBits(readAll(*source), first));  // the first pass
            if (rename) {
                std::filesystem::rename(other, path);
            } else {
                // In place: the same inode, a later modification time (set, as two writes may
                // fall within one tick of the file system's clock).
                const auto before = std::filesystem::last_write_time(path);
                std::filesystem::copy_file(other, path, std::filesystem::copy_options::overwrite_existing);
                std::filesystem::last_write_time(path, before + std::chrono::seconds(1));
                // A .gltf's triangles are in its .bin when large, else in the JSON, read once.
            }
            source->rewind();
            std::string error = "no error";
            try {
                readAll(*source);
            } catch (const InputError& e) {
                error = e.what();
            }
            if (std::string(name) == "x.gltf") {  // the buffer is a data URI in the JSON, parsed once: the first version throughout
                CHECK(error == "no error");
                continue;
            }
            CHECK_THAT(error, Catch::Contains(path + ": file changed while it was being read"));
        }
}
