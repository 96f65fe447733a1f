// One OBJ, one reading (issue #12): the blocker stream and the receiver meshes parse it with the
// same tokenizer, so they give the same coordinates bit for bit and the same errors; o/g groups
// are parts; vertices beyond the resident window spill to a scratch file and read back exactly;
// and the bucket pass never writes what the reach culls drop.

#include "CliRunner.h"

#include "stream/util/Error.h"
#include "stream/IndexedMesh.h"
#include "stream/ObjReader.h"
#include "stream/util/Npy.h"
#include "stream/Transform.h"
#include "stream/VertexStore.h"

#include <catch2/catch.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

#include <cstring>

using namespace penumbra;
using namespace penumbra::test;

namespace {

bool sameBits(const glm::vec3& a, const glm::vec3& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

/// The corners of every triangle of @p meshes, in order.
std::vector<glm::vec3> meshCorners(const std::vector<IndexedMesh>& meshes) {
    std::vector<glm::vec3> out;
    for (const IndexedMesh& m : meshes)
        for (uint32_t i : m.indices) out.push_back(m.position[i]);
    return out;
}

std::vector<glm::vec3> streamCorners(TriangleSource& source) {
    std::vector<glm::vec3> out;
    for (const Triangle& t : readAll(source)) out.insert(out.end(), t.v.begin(), t.v.end());
    return out;
}

const char* kAwkward =
    "# every case the two readers used to read differently\n"
    "o first\n"
    "v +1 0 0\n"
    "v 1.00000005960464477539062500000001 2.5e-1 -0\n"
    "v 0.1 0.2 0.3 # a comment after a vertex\n"
    "v 3.4028234663852886e+38 -1e-45 7\n"
    "vt +0.5 1\n"
    "vt 0.25 0.75 0\n"
    "vn 0 +1 0\n"
    "f 1/1/1 2/2/1 3/1/1 # a comment after a face\n"
    "g second part\n"
    "f -1 -2 -3 -4\n"
    "f 4//1 3//1 1//1\n";

}  // namespace

TEST_CASE("OBJ: blockers and receivers read the same bits", "[obj][receivers]") {
    ScratchDir dir("obj-agree");
    std::ofstream(dir / "awkward.obj") << kAwkward;
    const std::string path = dir / "awkward.obj";
    // Identity, and a transform that rounds (the same float arithmetic for both).
    const glm::mat4 turn = glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(0.3f, -2.0f, 7.1f)), 0.7f, glm::vec3(0.2f, 1.0f, 0.1f));
    for (const glm::mat4& m : {glm::mat4(1.0f), turn}) {
        TriangleSourcePtr blockers = openObj(path);
        if (m != glm::mat4(1.0f)) blockers = std::make_unique<TransformedSource>(std::move(blockers), m);
        const std::vector<glm::vec3> stream = streamCorners(*blockers);
        const std::vector<glm::vec3> receivers = meshCorners(loadIndexedMeshes(path, m));
        REQUIRE(stream.size() == 12);
        REQUIRE(receivers.size() == stream.size());
        for (size_t i = 0; i < stream.size(); ++i) {
            INFO("corner " << i);
            CHECK(sameBits(stream[i], receivers[i]));
        }
    }
    // Straight from decimal to float: the long literal rounds to 1 + 2^-23, not through double to 1.
    const std::vector<glm::vec3> identity = streamCorners(*openObj(path));
    CHECK(identity[1].x == 1.00000012f);
    CHECK(identity[0].x == 1.0f);
}

TEST_CASE("OBJ: both readers reject the same malformed statements with the same message", "[obj][receivers]") {
    ScratchDir dir("obj-errors");
    for (const char* text : {"vt x 0\n", "v 1 2\n", "vn 0 0 nan\n", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/2 2 3\n",
                             "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2 3\n", "v 0 0 0\nf 1 2\n"}) {
        INFO(text);
        std::ofstream(dir / "bad.obj") << text;
        const std::string blocker = errorOf([&] { readAll(*openObj(dir / "bad.obj")); });
        const std::string receiver = errorOf([&] { loadIndexedMeshes(dir / "bad.obj", glm::mat4(1.0f)); });
        CHECK_THAT(blocker, Catch::StartsWith(dir / "bad.obj:"));
        CHECK(blocker == receiver);
    }
}

TEST_CASE("OBJ: o/g groups are meshes of their own, and a scene can pick them", "[obj][receivers]") {
    ScratchDir dir("obj-parts");
    std::ofstream(dir / "parts.obj") << kAwkward;
    const std::vector<IndexedMesh> meshes = loadIndexedMeshes(dir / "parts.obj", glm::mat4(1.0f));
    REQUIRE(meshes.size() == 2);
    CHECK(meshes[0].name == "first");
    CHECK(meshes[0].triangleCount() == 1);
    CHECK(meshes[1].name == "second part");
    CHECK(meshes[1].triangleCount() == 3);
    const std::vector<IndexedMesh> second = loadIndexedMeshes(dir / "parts.obj", glm::mat4(1.0f), {"second part"});
    REQUIRE(second.size() == 1);
    TriangleSourcePtr stream = openObj(dir / "parts.obj", {"second part"});
    CHECK(stream->sizeHint() == 3u);
    const std::vector<glm::vec3> a = streamCorners(*stream), b = meshCorners(second);
    REQUIRE(a.size() == b.size());
    for (size_t i = 0; i < a.size(); ++i) CHECK(sameBits(a[i], b[i]));
    CHECK_THAT(errorOf([&] { readAll(*openObj(dir / "parts.obj", {"third"})); }), Catch::Contains("no o/g group named \"third\""));
    CHECK_THAT(errorOf([&] { loadIndexedMeshes(dir / "parts.obj", glm::mat4(1.0f), {"third"}); }),
               Catch::Contains("no o/g group named \"third\""));
}

TEST_CASE("OBJ: vertices beyond the window spill to a scratch file and read back exactly", "[obj][outofcore]") {
    VertexStore store("test.obj", 1000);
    std::vector<glm::vec3> all;
    for (int i = 0; i < 50'000; ++i) {
        const glm::vec3 p(float(i) * 0.37f, std::sin(float(i)), -float(i) / 7.0f);
        all.push_back(p);
        store.push(p);
    }
    CHECK(store.spilledBytes() >= (50'000 - 1000 - VertexStore::kVertexBlock) * 12);
    // In order, backwards and jumping: every read is the vertex pushed.
    for (uint64_t i = 0; i < all.size(); ++i) REQUIRE(sameBits(store[i], all[i]));
    for (uint64_t i = all.size(); i-- > 0;) REQUIRE(sameBits(store[i], all[i]));
    for (uint64_t i = 0, j = 0; i < all.size(); ++i, j = (j + 7919) % all.size()) REQUIRE(sameBits(store[j], all[j]));
    CHECK(VertexStore::residentBytes(1ull << 40) < 32ull << 20);
}

TEST_CASE("cull before spill: the culled fraction is never written, and the masks do not change", "[outofcore][buckets]") {
    // A rect light above, and a sun: its reach is the receivers swept along its cone of directions.
    const nlohmann::json rect = {{"type", "rect"}, {"center", {0, 5, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}, {"samples", 64}};
    const nlohmann::json sun = {{"type", "sun"}, {"direction", {0.3, -1, 0.2}}, {"angular_diameter_deg", 4}, {"samples", 64}};
    for (const nlohmann::json& light : {rect, sun}) {
        INFO(light["type"]);
        ScratchDir dir("cull-spill");
        nlohmann::json s = {
            {"geometry",
             {{{"type", "grid"}, {"levels", 1}, {"cells", 6}, {"size", 3}, {"floor_size", 6}},
              {{"type", "grass"}, {"count", 20'000}, {"area", {{-2, -2}, {2, 2}}}, {"seed", 4}},     // in reach
              {{"type", "grass"}, {"count", 60'000}, {"area", {{30, 30}, {90, 90}}}, {"seed", 5}}}},  // far away
            {"lights", {light}},
            {"receivers", {{"type", "camera"}, {"eye", {0, 5, 6}}, {"target", {0, 0, 0}}, {"width", 80}, {"height", 60}}},
            {"output", "out.exr"}};
        std::ofstream(dir / "scene.json") << s.dump();
        auto run = [&](const std::string& name, const std::string& extra) {
            RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q --tmp " + dir.path.string() + " --dump " + (dir / name) +
                                      " --stats " + (dir / (name + ".json")) + " " + extra);
            INFO(r.err);
            REQUIRE(r.exitCode == 0);
            return nlohmann::json::parse(slurp(dir / (name + ".json")));
        };
        const nlohmann::json on = run("on", ""), off = run("off", "--disable cull-before-spill");
        const uint64_t triangles = on["counters"]["triangles_read"], culled = on["buckets"]["triangles_culled"];
        CHECK(culled >= 5 * 60'000);  // the far grass, at least (five triangles a blade)
        CHECK(off["buckets"]["triangles_culled"] == 0);
        CHECK(off["buckets"]["bytes_written"].get<uint64_t>() == 40 * triangles);
        CHECK(on["buckets"]["bytes_written"].get<uint64_t>() == 40 * (triangles - culled));
        CHECK(on["counters"]["triangles_culled_at_root"] == off["counters"]["triangles_culled_at_root"]);
        CHECK(readNpy(dir / "on/masks.npy").data == readNpy(dir / "off/masks.npy").data);
        // The write rate is of the writing: of the whole pass (mostly reading and culling when
        // the cull is on) it read 0-1 MB/s.
        for (const nlohmann::json* stats : {&on, &off}) {
            const nlohmann::json& b = (*stats)["buckets"];
            CHECK(b["write_time_s"].get<double>() <= b["pass_time_s"].get<double>());
            if (b["write_time_s"].get<double>() > 0)
                CHECK(b["write_mb_per_s"].get<double>() ==
                      Approx(double(b["bytes_written"].get<uint64_t>()) / 1e6 / b["write_time_s"].get<double>()));
            CHECK((*stats)["stream"]["open_time_s"].get<double>() >= 0.0);
        }
    }
}

TEST_CASE("OBJ: every truncated prefix and damaged byte fails cleanly, the same way for both readers", "[obj][robustness]") {
    ScratchDir dir("obj-damage");
    const std::string good = kAwkward;
    auto check = [&](const std::string& text, const std::string& what) {
        INFO(what);
        std::ofstream(dir / "d.obj", std::ios::binary) << text;
        std::string blocker = "ok", receiver = "ok";
        try {
            for (const Triangle& t : readAll(*openObj(dir / "d.obj"))) CHECK(isFinite(t));
        } catch (const InputError& e) {
            blocker = e.what();
        }
        try {
            loadIndexedMeshes(dir / "d.obj", glm::mat4(1.0f));
        } catch (const InputError& e) {
            receiver = e.what();
        }
        CHECK(blocker.find('\n') == std::string::npos);
        if (blocker != "ok") CHECK_THAT(blocker, Catch::StartsWith(dir / "d.obj"));
        CHECK(blocker == receiver);
    };
    for (size_t length = 0; length < good.size(); ++length) check(good.substr(0, length), "prefix of " + std::to_string(length));
    for (size_t i = 0; i < good.size(); ++i) {
        std::string text = good;
        text[i] = char(text[i] ^ 0x21);
        check(text, "byte " + std::to_string(i) + " damaged");
    }
}

TEST_CASE("OBJ: a full disk while spilling vertices is one clean line", "[obj][outofcore][robustness]") {
    ScratchDir dir("obj-spill-full");
    nlohmann::json gen = {{"geometry", {{{"type", "grass"}, {"count", 120'000}, {"area", {{40, 40}, {80, 80}}}, {"seed", 2}}}},
                          {"lights", {{{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}}}},
                          {"receivers", {{"type", "camera"}, {"eye", {0, 4, 5}}, {"target", {0, 0, 0}}, {"width", 16}, {"height", 12}}},
                          {"output", "out.exr"}};
    std::ofstream(dir / "gen.json") << gen.dump();
    REQUIRE(runPenumbra("generate " + (dir / "gen.json") + " -q -o " + (dir / "g.obj")).exitCode == 0);  // 1.8M vertices
    gen["geometry"] = {{{"type", "obj"}, {"path", dir / "g.obj"}}};
    std::ofstream(dir / "bake.json") << gen.dump();
    RunResult r = runPenumbra("bake " + (dir / "bake.json") + " -q --tmp " + dir.path.string(), "prlimit --fsize=1000000");
    INFO(r.err);
    CHECK(r.exitCode == 1);
    CHECK(lineCount(r.err) == 1);
    CHECK_THAT(r.err, Catch::Contains("cannot write the scratch file for the vertices of") && Catch::Contains("g.obj"));
    CHECK_FALSE(std::filesystem::exists(dir / "out.exr"));
}
