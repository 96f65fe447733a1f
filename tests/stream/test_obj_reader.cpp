// Tests for the streaming OBJ reader: syntax coverage, index resolution, error messages with
// file:line, real meshes, and robustness against truncated or damaged files.

#include "stream/util/Error.h"
#include "stream/ObjReader.h"
#include "stream/VertexStore.h"
#include <fmt/format.h>
#include "StreamTestFiles.h"
#include "CliRunner.h"

#include <catch2/catch.hpp>

#include <map>

using namespace penumbra;
using namespace penumbra::test;

namespace {

std::vector<Triangle> readObjText(ScratchDir& dir, std::string_view text, const std::string& name = "mesh.obj") {
    writeText(dir.file(name), text);
    TriangleSourcePtr source = openObj(dir.file(name));
    return readAll(*source);
}

/// The message openObj gives for @p text, with the temp directory stripped so it can be compared.
std::string objError(ScratchDir& dir, std::string_view text) {
    writeText(dir.file("mesh.obj"), text);
    try {
        TriangleSourcePtr source = openObj(dir.file("mesh.obj"));
        readAll(*source);
    } catch (const InputError& e) {
        std::string message = e.what();
        std::string prefix = dir.path.string() + "/";
        if (message.rfind(prefix, 0) == 0) message.erase(0, prefix.size());
        return message;
    }
    return "no error";
}

const char* kSquare =
    "v 0 0 0\n"
    "v 1 0 0\n"
    "v 1 1 0\n"
    "v 0 1 0\n";

}  // namespace

TEST_CASE("OBJ: triangles and fan-triangulated convex polygons", "[stream][obj]") {
    ScratchDir dir("obj");
    std::string text = std::string(kSquare) + "v -0.5 0.5 0\nf 1 2 3\nf 1 2 3 4\nf 1 2 3 4 5\n";
    auto tris = readObjText(dir, text);
    REQUIRE(tris.size() == 1 + 2 + 3);
    // Fan order: (c0, c1, c2), (c0, c2, c3), ... (concave faces: test_polygon_triangulation.cpp)
    CHECK(sameBits(tris[0], tri({0, 0, 0}, {1, 0, 0}, {1, 1, 0})));
    CHECK(sameBits(tris[1], tri({0, 0, 0}, {1, 0, 0}, {1, 1, 0})));
    CHECK(sameBits(tris[2], tri({0, 0, 0}, {1, 1, 0}, {0, 1, 0})));
    CHECK(sameBits(tris[5], tri({0, 0, 0}, {0, 1, 0}, {-0.5f, 0.5f, 0})));
}

TEST_CASE("OBJ: all corner forms, texture and normal data ignored", "[stream][obj]") {
    ScratchDir dir("obj");
    std::string text = std::string(kSquare) +
                       "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n"
                       "f 1 2 3\n"
                       "f 1/1 2/2 3/3\n"
                       "f 1//1 2//1 3//1\n"
                       "f 1/1/1 2/2/1 3/3/1\n";
    auto tris = readObjText(dir, text);
    REQUIRE(tris.size() == 4);
    for (const Triangle& t : tris) CHECK(sameBits(t, tris[0]));
}

TEST_CASE("OBJ: negative indices count back from the face", "[stream][obj]") {
    ScratchDir dir("obj");
    auto tris = readObjText(dir,
                            "v 1 0 0\nv 2 0 0\nv 3 0 0\nvt 0 0\nvt 1 1\nvn 0 0 1\n"
                            "f -3 -2 -1\n"
                            "v 4 0 0\nv 5 0 0\nv 6 0 0\n"
                            "f -3 -2 -1\n"
                            "f 1 -1 -6\n"
                            "f -1/1/1 -2//1 -3/2\n");
    REQUIRE(tris.size() == 4);
    CHECK(sameBits(tris[0], tri({1, 0, 0}, {2, 0, 0}, {3, 0, 0})));
    CHECK(sameBits(tris[1], tri({4, 0, 0}, {5, 0, 0}, {6, 0, 0})));
    CHECK(sameBits(tris[2], tri({1, 0, 0}, {6, 0, 0}, {1, 0, 0})));
    CHECK(sameBits(tris[3], tri({6, 0, 0}, {5, 0, 0}, {4, 0, 0})));
}

TEST_CASE("OBJ: other statements, comments, CRLF and number spellings", "[stream][obj]") {
    ScratchDir dir("obj");
    auto tris = readObjText(dir,
                            "# comment line\r\n"
                            "mtllib scene.mtl\r\n"
                            "o thing\r\ng group\r\ns 1\r\nusemtl stone\r\n"
                            "\r\n"
                            "   v\t+1.5e1  -0 .25   1.0 # vertex with w\r\n"
                            "v 1 2 3 0.1 0.2 0.3\r\n"
                            "v 1E-2 -2.5E+2 7\r\n"
                            "vp 0.5\r\nl 1 2\r\np 1\r\ncstype bezier\r\n"
                            "\tf 1 2 3 # trailing comment\r\n"
                            "f 3 2 1");  // no final newline
    REQUIRE(tris.size() == 2);
    CHECK(sameBits(tris[0], tri({15, -0.0f, 0.25f}, {1, 2, 3}, {0.01f, -250, 7})));
    CHECK(std::signbit(tris[0].v[0].y));
}

TEST_CASE("OBJ: a UTF-8 byte order mark is skipped, a carriage return inside a line is no space", "[stream][obj]") {
    // Windows tools start files with a BOM. Kept, it made line 1 an unknown statement: the first
    // vertex was lost, and every face index pointed one vertex later (exit 0, wrong geometry).
    ScratchDir dir("obj");
    const std::string bom = "\xEF\xBB\xBF";
    auto tris = readObjText(dir, bom + "v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nv 5 5 5\r\nf 1 2 3\r\n");
    REQUIRE(tris.size() == 1);
    CHECK(sameBits(tris[0], tri({0, 0, 0}, {1, 0, 0}, {0, 1, 0})));
    // Only at the start of the file: later, the bytes are a damaged token.
    CHECK(objError(dir, "v 0 0 0\n" + bom + "v 1 0 0\n") == "no error");  // an unknown statement, as before
    CHECK(objError(dir, "v 0 0 " + bom + "1\n") == "mesh.obj:1: unparsable number '" + bom + "1'");  // UTF-8, kept
    // A CR inside a line is damage, not a separator (the README's example of a quoted token).
    CHECK(objError(dir, "v 1.7\r960 0 0\n") == "mesh.obj:1: unparsable number '1.7\\x0d960'");
    // Line ends with several CRs still read (CR CR LF, from a file converted twice).
    CHECK(readObjText(dir, "v 0 0 0\r\r\nv 1 0 0\r\r\nv 0 1 0\r\r\nf 1 2 3\r\r\n").size() == 1);
}

TEST_CASE("OBJ: sizeHint, chunked reads and rewind", "[stream][obj]") {
    ScratchDir dir("obj");
    std::string text;
    for (int i = 0; i < 12; ++i) text += fmt::format("v {} {} 0\n", std::cos(i * 0.5), std::sin(i * 0.5));
    text += "f 1 2 3 4 5 6 7 8 9 10 11 12\nf 1 2 3\n";  // a 10-triangle fan, then one more
    writeText(dir.file("fan.obj"), text);
    TriangleSourcePtr source = openObj(dir.file("fan.obj"));
    CHECK(source->sizeHint() == 11u);
    CHECK(source->name() == dir.file("fan.obj"));
    std::vector<Triangle> whole = readAll(*source);
    REQUIRE(whole.size() == 11);

    // Spans smaller than a polygon's fan must resume mid-polygon.
    for (size_t span : {1, 3, 4, 7}) {
        source->rewind();
        std::vector<Triangle> pieces, buffer(span);
        while (size_t n = source->read(buffer)) pieces.insert(pieces.end(), buffer.begin(), buffer.begin() + n);
        CHECK(sameBits(pieces, whole));
        CHECK(source->read(buffer) == 0);  // and stays at the end
    }
}

TEST_CASE("OBJ: a file changed between passes is an error, not another mesh", "[stream][obj]") {
    // A bake reads a large OBJ twice, minutes apart; one cut in between baked half the mesh, exit 0.
    ScratchDir dir("obj");
    const std::string path = dir.file("m.obj");
    const std::string full = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n";
    auto changedTo = [&](const std::string& text) {
        writeText(path, full);
        TriangleSourcePtr source = openObj(path);
        REQUIRE(source->sizeHint() == 2u);  // the check pass
        writeText(path, text);
        try {
            readAll(*source);
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    CHECK_THAT(changedTo(full.substr(0, full.size() - 8)), Catch::Contains("m.obj: file changed while it was being read"));
    // The same size, one face fewer: counted at the end of the pass.
    std::string sameSize = full;
    sameSize.replace(sameSize.size() - 8, 8, "# 2 4 3\n");
    REQUIRE(sameSize.size() == full.size());
    // Caught as the pass starts when the file's modification time moved (FileStamp), else by the
    // count at the end of the pass (two writes within one tick of the file system's clock).
    CHECK_THAT(changedTo(sameSize), Catch::Contains("m.obj: file changed while it was being read"));
}

TEST_CASE("OBJ: files without faces", "[stream][obj]") {
    ScratchDir dir("obj");
    CHECK(readObjText(dir, "").empty());
    CHECK(readObjText(dir, "# nothing\n\n").empty());
    CHECK(readObjText(dir, kSquare).empty());
    writeText(dir.file("v.obj"), kSquare);
    CHECK(openObj(dir.file("v.obj"))->sizeHint() == 0u);
}

TEST_CASE("OBJ: errors name the file and line", "[stream][obj]") {
    ScratchDir dir("obj");
    std::string square = kSquare;  // lines 1-4
    CHECK(objError(dir, square + "f 1 2 5\n") == "mesh.obj:5: face index 5 out of range (4 vertices)");
    CHECK(objError(dir, square + "f 1 2 -5\n") == "mesh.obj:5: face index -5 out of range (4 vertices)");
    CHECK(objError(dir, square + "f 1 0 2\n") == "mesh.obj:5: face index 0 is invalid (OBJ indices start at 1)");
    CHECK(objError(dir, square + "f 1 2\n") == "mesh.obj:5: face has 2 corners (needs at least 3)");
    CHECK(objError(dir, square + "f\n") == "mesh.obj:5: face has 0 corners (needs at least 3)");
    CHECK(objError(dir, "v 1 2 x\n") == "mesh.obj:1: unparsable number 'x'");
    CHECK(objError(dir, "v 1 2 3.0.0\n") == "mesh.obj:1: unparsable number '3.0.0'");
    CHECK(objError(dir, "v 1 2\n") == "mesh.obj:1: vertex has 2 coordinates (needs 3)");
    CHECK(objError(dir, "v 1 2 3 w\n") == "mesh.obj:1: unparsable number 'w'");
    // A damaged file's bytes are quoted escaped, so the error stays one printable line.
    CHECK(objError(dir, "v 0 0 \x01\n") == "mesh.obj:1: unparsable number '\\x01'");
    CHECK(objError(dir, "v 1 2 3\xff\n") == "mesh.obj:1: unparsable number '3\\xff'");
    CHECK(objError(dir, "v 0 0 1\xc3\xa9\n") == "mesh.obj:1: unparsable number '1\xc3\xa9'");  // UTF-8 kept
    CHECK(objError(dir, "\nv nan 0 0\n") == "mesh.obj:2: non-finite coordinate 'nan'");
    CHECK(objError(dir, "v 0 inf 0\n") == "mesh.obj:1: non-finite coordinate 'inf'");
    // 1e39 is finite; it overflows a float.
    CHECK(objError(dir, "v 0 0 1e39\n") == "mesh.obj:1: coordinate '1e39' is out of the float range (at most 3.40282e+38 in magnitude)");
    // A long token is cut (a 10 MB number was quoted up to the 9 KiB line cut).
    CHECK(objError(dir, "v 0 0 " + std::string(100000, '1') + "x\n") ==
          "mesh.obj:1: unparsable number '" + std::string(32, '1') + "...' (100001 characters)");
    CHECK(objError(dir, square + "f 1 2 x\n") == "mesh.obj:5: unparsable face corner 'x'");
    CHECK(objError(dir, square + "f 1 2 3/\n") == "no error");  // an empty vt field is harmless
    CHECK(objError(dir, square + "f 1 2 3/x\n") == "mesh.obj:5: unparsable face corner '3/x'");
    CHECK(objError(dir, square + "f 1 2 3/1/1/1\n") == "mesh.obj:5: unparsable face corner '3/1/1/1'");
    CHECK(objError(dir, square + "f 1 2 \\\n 3\n") ==
          "mesh.obj:5: ends in '\\': line continuations are not read; join the face's corners on one line");
    CHECK(objError(dir, square + "f 1 2 /1\n") == "mesh.obj:5: unparsable face corner '/1'");
    CHECK(objError(dir, square + "f 1 2 99999999999999999999\n") ==
          "mesh.obj:5: unparsable face corner '99999999999999999999'");
    // A face may only use vertices defined above it.
    CHECK(objError(dir, "v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n") == "mesh.obj:3: face index 3 out of range (2 vertices)");
    CHECK(objError(dir, "v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n") ==
          "mesh.obj:3: face index -3 out of range (2 vertices)");

    CHECK(objError(dir, "v +-1 0 0\n") == "mesh.obj:1: unparsable number '+-1'");
    CHECK(objError(dir, "v 0x10 0 0\n") == "mesh.obj:1: unparsable number '0x10'");
    CHECK(objError(dir, "v 0 1e400 0\n") == "mesh.obj:1: coordinate '1e400' is out of the float range (at most 3.40282e+38 in magnitude)");

    // Underflow is not an error: denormals keep their value, smaller numbers become zero.
    auto tiny = readObjText(dir, square + "v 1e-40 -1e-45 1e-400\nv -1e-999 0 0\nf 5 6 1\n");
    REQUIRE(tiny.size() == 1);
    CHECK(tiny[0].v[0].x == 1e-40f);
    CHECK(tiny[0].v[0].y == -1e-45f);
    CHECK(tiny[0].v[0].z == 0.0f);
    CHECK(std::signbit(tiny[0].v[1].x));
}

TEST_CASE("OBJ: a missing file is an input error naming it", "[stream][obj]") {
    ScratchDir dir("obj");
    std::string missing = dir.file("nope.obj");
    try {
        openObj(missing);
        FAIL("no error");
    } catch (const InputError& e) {
        CHECK(std::string(e.what()).find(missing + ": cannot open") == 0);
    }
    CHECK_THROWS_AS(openObj(dir.path.string()), InputError);  // a directory
}

TEST_CASE("OBJ: real meshes have their documented face counts", "[stream][obj][data]") {
    std::map<std::string, uint64_t> expected = {
        {"stanford-bunny.obj", 69451}, {"spot.obj", 5856},      {"cow.obj", 5804},    {"teapot.obj", 6320},
        {"beast.obj", 64618 /* quads */}, {"ogre.obj", 124008}, {"nefertiti.obj", 99938},
    };
    for (const auto& [name, count] : expected) {
        INFO(name);
        TriangleSourcePtr source = openObj(sharedData("meshes/") + name);
        CHECK(source->sizeHint() == count);
        uint64_t seen = 0, bad = 0;
        std::vector<Triangle> chunk(kTriangleChunk);
        while (size_t n = source->read(chunk)) {
            seen += n;
            for (size_t i = 0; i < n; ++i) bad += !isFinite(chunk[i]);
        }
        CHECK(seen == count);
        CHECK(bad == 0);
    }
}

TEST_CASE("OBJ: every truncated prefix and damaged byte fails cleanly or parses", "[stream][obj][robustness]") {
    ScratchDir dir("obj");
    const std::string text =
        "# test\nv 0 0 0\nv 1.5 0 0\nv 1 1 0\nv -0 1e-3 2\nvt 0 1\nvn 0 0 1\n"
        "f 1 2 3\nf 1/1 2/1 3/1 4/1\nf -1//1 -2//1 -3//1\nf 4 3 2 1\no x\nv 2 2 2\nf -1 1 2\n";
    const std::string path = dir.file("cut.obj");
    auto attempt = [&](std::string_view bytes) {
        writeText(path, bytes);
        try {
            TriangleSourcePtr source = openObj(path);
            std::vector<Triangle> tris = readAll(*source);
            CHECK(tris.size() == source->sizeHint());
            for (const Triangle& t : tris) CHECK(isFinite(t));
        } catch (const InputError&) {
            // a clean rejection is fine
        }
    };
    for (size_t length = 0; length <= text.size(); ++length) attempt(std::string_view(text).substr(0, length));
    for (size_t i = 0; i < text.size(); ++i)
        for (char replacement : {'x', '-', '/', '9', '0', '\n', ' ', '\0', '#', 'e'}) {
            std::string damaged = text;
            damaged[i] = replacement;
            attempt(damaged);
        }
}

TEST_CASE("OBJ: sources hold no descriptor between passes", "[stream][obj]") {
    ScratchDir dir("obj");
    writeText(dir.file("m.obj"), std::string(kSquare) + "f 1 2 3 4\nf 4 3 2\n");
    auto openDescriptors = [] {
        return std::distance(std::filesystem::directory_iterator("/proc/self/fd"), std::filesystem::directory_iterator());
    };
    auto before = openDescriptors();
    std::vector<TriangleSourcePtr> sources;
    for (int i = 0; i < 50; ++i) sources.push_back(openObj(dir.file("m.obj")));
    CHECK(openDescriptors() == before);
    std::vector<Triangle> one(1);
    CHECK(sources[0]->read(one) == 1);
    CHECK(openDescriptors() == before + 1);
    CHECK(readAll(*sources[0]).size() == 2);
    CHECK(openDescriptors() == before);
    sources[0]->rewind();
    CHECK(readAll(*sources[0]).size() == 3);
}

TEST_CASE("OBJ: the longest line and the largest face are in the source's working set", "[stream][obj]") {
    ScratchDir dir("obj-long-line");
    std::string text = std::string(kSquare) + "f 1 2 3\n#" + std::string(40u << 20, 'y') + "\nf 1 3 4\n";
    writeText(dir.file("long.obj"), text);
    TriangleSourcePtr source = openObj(dir.file("long.obj"));
    REQUIRE(source->sizeHint() == 2);  // the check pass, as on opening
    CHECK(source->residentBytes() >= 2 * (40ull << 20));  // getline(3)'s buffer grows by doubling
    CHECK_THAT(source->residentDetail(), Catch::Contains("longest line (41943042 bytes)"));
    CHECK(readAll(*source).size() == 2);
}

TEST_CASE("OBJ: once checked, the working set counts the vertices stored, not the file's bytes", "[stream][obj][memory]") {
    // Before the check the bound is the file's bytes over 8 (the shortest `v` line); real lines
    // are 30-40 bytes, and a scene of 48 mesh files was refused under a budget eleven times its
    // peak (the sum of 48 such bounds).
    ScratchDir dir("obj-working-set");
    std::string text;
    const int n = 20000;
    for (int i = 0; i < n; ++i) text += fmt::format("v {:.9f} {:.9f} {:.9f}\n", i * 1e-3, 0.5, -i * 2e-3);
    for (int i = 1; i + 2 <= n; i += 3) text += fmt::format("f {} {} {}\n", i, i + 1, i + 2);
    writeText(dir.file("m.obj"), text);
    TriangleSourcePtr source = openObj(dir.file("m.obj"));
    const uint64_t before = VertexStore::residentBytes(text.size() / 8);
    REQUIRE(source->sizeHint() == uint64_t(n / 3));
    const uint64_t lines = source->residentBytes() - VertexStore::residentBytes(n);
    CHECK(lines <= (1u << 16) + 64 * 200);  // the line buffer and a triangle's corners
    CHECK(source->residentBytes() < before / 4);
    CHECK(readAll(*source).size() == size_t(n / 3));
}

TEST_CASE("OBJ: a line too long for the memory left is an error naming it, not the end of the file", "[stream][obj][memory]") {
    // getline(3) returns -1 for a line it cannot grow its buffer for; the faces after it were
    // dropped, exit 0.
    ScratchDir dir("obj-long-line-limit");
    std::string text = std::string(kSquare) + "f 1 2 3\n#" + std::string(200u << 20, 'y') + "\nf 1 3 4\n";
    writeText(dir.file("long.obj"), text);
    text.clear(), text.shrink_to_fit();
    const RunResult r = runPenumbra("info " + dir.file("long.obj"), "prlimit --as=" + std::to_string(150u << 20));
    INFO(r.err);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.err, Catch::Contains("long.obj:6: a line of 209715202 bytes does not fit in memory"));
}

TEST_CASE("OBJ: materials that cut faces out with map_d are warned of, since they are not read", "[stream][obj][cli]") {
    ScratchDir dir("obj-map-d");
    writeText(dir.file("card.obj"), std::string("mtllib card.mtl\nusemtl leaf\n") + kSquare + "f 1 2 3 4\n");
    writeText(dir.file("card.mtl"), "newmtl leaf\nKd 0.2 0.6 0.2\n  map_d leaf-alpha.png\n");
    RunResult r = runPenumbra("info " + dir.file("card.obj"));
    INFO(r.err);
    CHECK(r.exitCode == 0);
    CHECK(occurrences(r.err, "card.mtl) cut faces out with map_d, which is not read") == 1);
    writeText(dir.file("card.mtl"), "newmtl leaf\nKd 0.2 0.6 0.2\nmap_Kd leaf.png\n");  // colour only: nothing to say
    CHECK(runPenumbra("info " + dir.file("card.obj")).err.find("map_d") == std::string::npos);
    std::filesystem::remove(dir.file("card.mtl"));  // a missing library is not an error (the mesh is whole)
    CHECK(runPenumbra("info " + dir.file("card.obj")).exitCode == 0);
}
