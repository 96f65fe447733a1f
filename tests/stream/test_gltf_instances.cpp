// glTF as real exports ship it (issue #12): instancing by nodes and by EXT_mesh_gpu_instancing
// gives the masks of the same scene written flat, with a peak RSS that does not grow with the
// instance count; EXT_meshopt_compression (gltfpack) and KHR_draco_mesh_compression
// (draco_transcoder) give the masks of their uncompressed originals; damaged files of every new
// reader path fail with one clean line.

#include "CliRunner.h"

#include "stream/util/Error.h"
#include "stream/GltfReader.h"
#include "stream/IndexedMesh.h"
#include "stream/util/Npy.h"

#include <catch2/catch.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstring>
#include <filesystem>

using namespace penumbra;
using namespace penumbra::test;

namespace {

using Json = nlohmann::json;

/// A .glb split into its JSON and BIN chunks.
struct Glb {
    Json json;
    std::string bin;
};

Glb readGlb(const std::string& path) {
    const std::string bytes = slurp(path);
    REQUIRE(bytes.size() >= 20);
    uint32_t jsonLength = 0, binLength = 0;
    std::memcpy(&jsonLength, bytes.data() + 12, 4);
    Glb g;
    g.json = Json::parse(bytes.substr(20, jsonLength));
    if (20 + jsonLength + 8 <= bytes.size()) {
        std::memcpy(&binLength, bytes.data() + 20 + jsonLength, 4);
        g.bin = bytes.substr(20 + jsonLength + 8, binLength);
    }
    return g;
}

void writeGlb(const std::string& path, const Glb& g) {
    std::string json = g.json.dump();
    json.resize((json.size() + 3) / 4 * 4, ' ');
    std::string bin = g.bin;
    bin.resize((bin.size() + 3) / 4 * 4, '\0');
    auto u32 = [](uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
    const uint32_t total = uint32_t(12 + 8 + json.size() + 8 + bin.size());
    std::ofstream(path, std::ios::binary) << "glTF" << u32(2) << u32(total) << u32(uint32_t(json.size())) << "JSON" << json
                                          << u32(uint32_t(bin.size())) << std::string("BIN\0", 4) << bin;
}

/// Appends @p values to the BIN chunk as a new bufferView and FLOAT accessor; returns its index.
int appendFloats(Glb& g, const std::vector<float>& values, const char* type, size_t count) {
    g.bin.resize((g.bin.size() + 3) / 4 * 4, '\0');
    const size_t offset = g.bin.size();
    g.bin.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
    g.json["buffers"][0]["byteLength"] = g.bin.size();
    g.json["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", values.size() * sizeof(float)}});
    g.json["accessors"].push_back({{"bufferView", g.json["bufferViews"].size() - 1}, {"componentType", 5126}, {"count", count},
                                   {"type", type}});
    return int(g.json["accessors"].size() - 1);
}

/// Instance i of n: a translation in whole units (most instances far outside the light's reach),
/// every other one turned 180 degrees about y, every third scaled by 2. All exact in float, so
/// the flat scene can be written independently of the reader's matrix code.
struct Placement {
    glm::vec3 t;
    bool turned;
    float scale;
};
Placement placement(size_t i) {
    const float far = i < 4 ? 0.0f : 60.0f + float(i % 40);
    return {glm::vec3(float(i % 4) - 1.5f + far, 0.0f, float(i / 4 % 4) - 1.5f + far), i % 2 == 1, i % 3 == 2 ? 2.0f : 1.0f};
}
glm::vec3 place(const Placement& p, glm::vec3 v) {
    v *= p.scale;
    if (p.turned) v.x = -v.x, v.z = -v.z;
    return glm::vec3(float(double(v.x) + p.t.x), float(double(v.y) + p.t.y), float(double(v.z) + p.t.z));
}

/// The base mesh: a small non-indexed grass patch (one FLOAT POSITION accessor), as a .glb.
std::string baseMesh(const ScratchDir& dir, uint64_t blades, const std::string& name = "base.glb") {
    Json gen = {{"geometry", {{{"type", "grass"}, {"count", blades}, {"area", {{-0.4, -0.4}, {0.4, 0.4}}}, {"seed", 11}}}},
                {"lights", {{{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}}}},
                {"receivers", {{"type", "camera"}, {"eye", {0, 4, 5}}, {"target", {0, 0, 0}}}}};
    std::ofstream(dir / "gen.json") << gen.dump();
    REQUIRE(runPenumbra("generate " + (dir / "gen.json") + " -q -o " + (dir / name)).exitCode == 0);
    return dir / name;
}

/// The instanced files (EXT_mesh_gpu_instancing on one node, and one node per instance) and the
/// flat OBJ of the same triangles.
void writeInstanced(const ScratchDir& dir, const std::string& base, size_t n, const std::string& tag, bool flat) {
    Glb g = readGlb(base);
    std::vector<float> t, r, s;
    for (size_t i = 0; i < n; ++i) {
        const Placement p = placement(i);
        t.insert(t.end(), {p.t.x, p.t.y, p.t.z});
        r.insert(r.end(), {0.0f, p.turned ? 1.0f : 0.0f, 0.0f, p.turned ? 0.0f : 1.0f});
        s.insert(s.end(), {p.scale, p.scale, p.scale});
    }
    Glb ext = g;
    const int ta = appendFloats(ext, t, "VEC3", n), ra = appendFloats(ext, r, "VEC4", n), sa = appendFloats(ext, s, "VEC3", n);
    ext.json["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {{"TRANSLATION", ta}, {"ROTATION", ra}, {"SCALE", sa}};
    ext.json["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
    writeGlb(dir / ("ext-" + tag + ".glb"), ext);

    Glb nodes = g;
    nodes.json["nodes"] = Json::array();
    nodes.json["scenes"][0]["nodes"] = Json::array();
    for (size_t i = 0; i < n; ++i) {
        nodes.json["nodes"].push_back({{"mesh", 0}, {"translation", {t[3 * i], t[3 * i + 1], t[3 * i + 2]}},
                                       {"rotation", {r[4 * i], r[4 * i + 1], r[4 * i + 2], r[4 * i + 3]}},
                                       {"scale", {s[3 * i], s[3 * i + 1], s[3 * i + 2]}}});
        nodes.json["scenes"][0]["nodes"].push_back(i);
    }
    writeGlb(dir / ("nodes-" + tag + ".glb"), nodes);
    if (!flat) return;
    // Flat: every instance's triangles written out, block by block as the reader streams them
    // (the order does not matter to masks; it is kept anyway).
    std::vector<glm::vec3> v(g.bin.size() / 12);
    std::memcpy(v.data(), g.bin.data(), v.size() * 12);
    std::ofstream obj(dir / ("flat-" + tag + ".obj"));
    size_t written = 0;
    for (size_t i = 0; i < n; ++i, written += v.size())
        for (size_t k = 0; k < v.size(); ++k) {
            const glm::vec3 p = place(placement(i), v[k]);
            obj << fmt::format("v {} {} {}\n", p.x, p.y, p.z);
            if (k % 3 == 2) obj << fmt::format("f {} {} {}\n", written + k - 1, written + k, written + k + 1);
        }
}

Json bakeScene(const std::string& geometry) {
    return {{"geometry", {{{"type", "file"}, {"path", geometry}}, {{"type", "grid"}, {"levels", 0}, {"floor_size", 6}}}},
            {"lights", {{{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}, {"samples", 64}, {"sample_sets", 4}}}},
            {"receivers", {{"type", "camera"}, {"eye", {0, 4, 5}}, {"target", {0, 0, 0}}, {"width", 96}, {"height", 72}}},
            {"output", "out.exr"}};
}

/// Bakes @p geometry with --dump; returns the masks and the stats.
std::pair<std::vector<uint8_t>, Json> masks(const ScratchDir& dir, const std::string& geometry, const std::string& extra = "") {
    std::ofstream(dir / "bake.json") << bakeScene(geometry).dump();
    const std::string dump = dir / ("dump-" + std::filesystem::path(geometry).stem().string());
    RunResult r = runPenumbra("bake " + (dir / "bake.json") + " -q --tmp " + dir.path.string() + " --dump " + dump + " --stats " +
                              (dir / "stats.json") + " " + extra);
    INFO(geometry << ": " << r.err);
    REQUIRE(r.exitCode == 0);
    return {readNpy(dump + "/masks.npy").data, Json::parse(slurp(dir / "stats.json"))};
}

bool haveTool(const char* name) { return std::system((std::string("command -v ") + name + " >/dev/null 2>&1").c_str()) == 0; }

/// Every prefix (every @p step bytes) and damaged byte (every @p step) of @p path either reads as
/// finite triangles or fails with one InputError line naming the file.
void damageCleanly(const std::string& path, size_t step) {
    const std::string good = slurp(path);
    const std::string bad = path + ".bad.glb";
    auto check = [&](const std::string& bytes, const std::string& what) {
        std::ofstream(bad, std::ios::binary) << bytes;
        INFO(what);
        try {
            const std::vector<Triangle> all = readAll(*openGltf(bad));
            CHECK(std::all_of(all.begin(), all.end(), [](const Triangle& t) { return isFinite(t); }));
        } catch (const InputError& e) {
            CHECK(std::string(e.what()).find('\n') == std::string::npos);
            CHECK_THAT(e.what(), Catch::Contains("bad.glb"));
        }
    };
    for (size_t length = 0; length < good.size(); length += step) check(good.substr(0, length), fmt::format("prefix of {}", length));
    for (size_t i = 0; i < good.size(); i += step) {
        std::string bytes = good;
        bytes[i] = char(bytes[i] ^ 0x5A);
        check(bytes, fmt::format("byte {} flipped", i));
    }
    std::filesystem::remove(bad);
}

}  // namespace

TEST_CASE("node instancing and EXT_mesh_gpu_instancing give the masks of the flat scene", "[gltf][instancing]") {
    ScratchDir dir("instances");
    const std::string base = baseMesh(dir, 400);
    writeInstanced(dir, base, 24, "24", true);
    const auto flat = masks(dir, dir / "flat-24.obj");
    const auto ext = masks(dir, dir / "ext-24.glb");
    const auto nodes = masks(dir, dir / "nodes-24.glb");
    CHECK(ext.second["counters"]["triangles_read"] == flat.second["counters"]["triangles_read"]);
    CHECK(nodes.second["counters"]["triangles_read"] == flat.second["counters"]["triangles_read"]);
    CHECK(ext.first == flat.first);
    CHECK(nodes.first == flat.first);
    CHECK(flat.second["blocked_relations"].get<uint64_t>() > 0);
}

TEST_CASE("receiver meshes and convert to glTF place every EXT_mesh_gpu_instancing instance", "[gltf][instancing]") {
    // The meshes that vertex and lightmap receivers are made on, and that `convert` writes as glTF,
    // were placed once at the node: the instances were dropped (2 triangles in, 1 out, exit 0).
    ScratchDir dir("instances");
    const std::string base = baseMesh(dir, 20);
    writeInstanced(dir, base, 6, "6", false);
    const std::vector<IndexedMesh> ext = loadIndexedMeshes(dir / "ext-6.glb", glm::mat4(1.0f), {});
    const std::vector<IndexedMesh> nodes = loadIndexedMeshes(dir / "nodes-6.glb", glm::mat4(1.0f), {});
    REQUIRE(ext.size() == 6);
    REQUIRE(nodes.size() == 6);
    for (size_t i = 0; i < 6; ++i) {
        INFO("instance " << i);
        REQUIRE(ext[i].position.size() == nodes[i].position.size());
        for (size_t v = 0; v < ext[i].position.size(); ++v) CHECK(glm::length(ext[i].position[v] - nodes[i].position[v]) < 1e-5f);
        CHECK(ext[i].indices == nodes[i].indices);  // mirrored instances flip the winding alike
    }
    // convert keeps them: the same triangle count and bounds as the file converted to .ptri.
    REQUIRE(runPenumbra("convert -q " + (dir / "ext-6.glb") + " " + (dir / "ext-6-out.glb")).exitCode == 0);
    REQUIRE(runPenumbra("convert -q " + (dir / "ext-6.glb") + " " + (dir / "ext-6-out.ptri")).exitCode == 0);
    RunResult in = runPenumbra("info -q " + (dir / "ext-6.glb"));
    RunResult a = runPenumbra("info -q " + (dir / "ext-6-out.glb")), b = runPenumbra("info -q " + (dir / "ext-6-out.ptri"));
    CHECK_THAT(in.out, Catch::StartsWith("triangles "));
    CHECK(a.out == in.out);
    CHECK(b.out == in.out);
}

TEST_CASE("peak RSS does not grow with the instance count", "[gltf][instancing][outofcore][memory]") {
    ScratchDir dir("instance-rss");
    const std::string base = baseMesh(dir, 4000);  // 20K triangles
    writeInstanced(dir, base, 10, "10", false);
    writeInstanced(dir, base, 1000, "1000", false);  // 20M triangles from a file of about 1 MB
    for (const char* kind : {"ext", "nodes"}) {
        INFO(kind);
        const Json few = masks(dir, dir / fmt::format("{}-10.glb", kind)).second;
        const Json many = masks(dir, dir / fmt::format("{}-1000.glb", kind)).second;
        const uint64_t floor = 2;  // the grid entry's floor quad
        CHECK(many["counters"]["triangles_read"].get<uint64_t>() - floor ==
              100 * (few["counters"]["triangles_read"].get<uint64_t>() - floor));
        const double a = few["counters"]["peak_rss_bytes"], b = many["counters"]["peak_rss_bytes"];
        INFO("peak RSS 10 instances: " << a / 1e6 << " MB, 1000: " << b / 1e6 << " MB");
        CHECK(b < 1.10 * a);
    }
}

TEST_CASE("EXT_meshopt_compression from gltfpack gives the masks of the uncompressed file, bit for bit", "[gltf][compression]") {
    REQUIRE(haveTool("gltfpack"));  // setup.sh installs it
    ScratchDir dir("meshopt");
    const std::string base = baseMesh(dir, 2000);
    // Quantized (KHR_mesh_quantization) with and without meshopt; and float positions (-noq).
    for (const std::string& args : {std::string(" -o ") + (dir / "q.glb"), std::string(" -cc -o ") + (dir / "qc.glb"),
                                    std::string(" -noq -c -o ") + (dir / "fc.glb")}) {
        const int status = std::system(("gltfpack -i " + base + args + " >/dev/null 2>&1").c_str());
        REQUIRE(status == 0);
    }
    CHECK_THAT(slurp(dir / "qc.glb"), Catch::Contains("EXT_meshopt_compression"));
    CHECK(masks(dir, dir / "qc.glb").first == masks(dir, dir / "q.glb").first);
    CHECK(masks(dir, dir / "fc.glb").first == masks(dir, base).first);
    damageCleanly(dir / "qc.glb", 97);
}

TEST_CASE("KHR_draco_mesh_compression gives the masks of its decoded positions", "[gltf][compression]") {
    REQUIRE(haveTool("draco_transcoder"));  // Debian's draco package, installed by setup.sh
    ScratchDir dir("draco");
    const std::string base = baseMesh(dir, 2000);
    REQUIRE(std::system(("draco_transcoder -i " + base + " -o " + (dir / "d.glb") + " >/dev/null 2>&1").c_str()) == 0);
    CHECK_THAT(slurp(dir / "d.glb"), Catch::Contains("KHR_draco_mesh_compression"));
    // The decoded positions, written flat, and the original: same triangles, within the 11-bit
    // position quantization of the original's extent.
    REQUIRE(runPenumbra("convert " + (dir / "d.glb") + " " + (dir / "decoded.ptri")).exitCode == 0);
    const std::vector<Triangle> original = readAll(*openGltf(base)), decoded = readAll(*openGltf(dir / "d.glb"));
    REQUIRE(decoded.size() == original.size());
    glm::vec3 lo(INFINITY), hi(-INFINITY), dlo(INFINITY), dhi(-INFINITY);
    for (size_t i = 0; i < original.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            lo = glm::min(lo, original[i].v[c]), hi = glm::max(hi, original[i].v[c]);
            dlo = glm::min(dlo, decoded[i].v[c]), dhi = glm::max(dhi, decoded[i].v[c]);
        }
    const glm::vec3 extent = hi - lo;
    const float quantum = std::max({extent.x, extent.y, extent.z}) / 2047.0f;
    CHECK(glm::all(glm::lessThanEqual(glm::abs(dlo - lo), glm::vec3(quantum))));
    CHECK(glm::all(glm::lessThanEqual(glm::abs(dhi - hi), glm::vec3(quantum))));
    CHECK(masks(dir, dir / "d.glb").first == masks(dir, dir / "decoded.ptri").first);
    damageCleanly(dir / "d.glb", 53);
}

TEST_CASE("a compressed primitive larger than the budget is an error saying what it needs", "[gltf][compression][memory]") {
    REQUIRE(haveTool("draco_transcoder"));
    ScratchDir dir("draco-budget");
    const std::string base = baseMesh(dir, 200'000);  // one primitive of a million triangles
    REQUIRE(std::system(("draco_transcoder -i " + base + " -o " + (dir / "d.glb") + " >/dev/null 2>&1").c_str()) == 0);
    std::ofstream(dir / "bake.json") << bakeScene(dir / "d.glb").dump();
    RunResult r = runPenumbra("bake " + (dir / "bake.json") + " -q --memory-budget 64M");
    INFO(r.err);
    CHECK(r.exitCode == 1);
    CHECK(lineCount(r.err) == 1);
    CHECK_THAT(r.err, Catch::Contains("d.glb: mesh 0 primitive 0 needs") && Catch::Contains("to decode") && Catch::Contains("at least"));
}

TEST_CASE("damaged instanced files and external buffers fail cleanly", "[gltf][instancing][robustness]") {
    ScratchDir dir("instances-damaged");
    writeInstanced(dir, baseMesh(dir, 20), 6, "6", false);
    damageCleanly(dir / "ext-6.glb", 7);
    // An external .bin shorter than its byteLength, and one cut after the file was opened.
    Glb g = readGlb(dir / "ext-6.glb");
    std::ofstream(dir / "ext.bin", std::ios::binary) << g.bin.substr(0, g.bin.size() / 2);
    g.json["buffers"][0]["uri"] = "ext.bin";
    std::ofstream(dir / "ext.gltf") << g.json.dump();
    CHECK_THAT(errorOf([&] { readAll(*openGltf(dir / "ext.gltf")); }),
               Catch::Contains("ext.gltf: buffer 0 (ext.bin) has") && Catch::Contains("but its byteLength is"));
    std::ofstream(dir / "ext.bin", std::ios::binary) << g.bin;
    TriangleSourcePtr source = openGltf(dir / "ext.gltf");
    std::filesystem::resize_file(dir / "ext.bin", 64);
    const std::string message = errorOf([&] { readAll(*source); });
    CHECK_THAT(message, Catch::Contains("ext.bin") && Catch::Contains("shorter"));
}

TEST_CASE("a data: URI buffer above the limit is refused, naming the buffer", "[gltf][robustness]") {
    ScratchDir dir("data-uri");
    const Json doc = {{"asset", {{"version", "2.0"}}},
                      {"buffers", {{{"byteLength", 20'000'000}, {"uri", "data:application/octet-stream;base64,AAAA"}}}}};
    std::ofstream(dir / "big.gltf") << doc.dump();
    CHECK_THAT(errorOf([&] { openGltf(dir / "big.gltf"); }),
               Catch::StartsWith(dir / "big.gltf: buffer 0: an embedded data: URI of 20000000 bytes is above the 16 MiB limit"));
    // A URI longer than its byteLength claims: the message names what the URI holds (it named
    // byteLength, 44 bytes "above the 16 MiB limit").
    const Json small = {{"asset", {{"version", "2.0"}}},
                        {"buffers", {{{"byteLength", 44}, {"uri", "data:application/octet-stream;base64," + std::string(24'000'000, 'A')}}}}};
    std::ofstream(dir / "long.gltf") << small.dump();
    CHECK_THAT(errorOf([&] { openGltf(dir / "long.gltf"); }),
               Catch::StartsWith(dir / "long.gltf: buffer 0: an embedded data: URI of 18000000 bytes is above the 16 MiB limit"));
}
