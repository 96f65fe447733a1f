// Lightmap receivers: conservative texel coverage, dilation, irradiance on a lit quad, overlap
// counting, OBJ/glTF agreement, parameter errors, and a CLI bake read back from the EXR.

#include "CliRunner.h"
#include "LightmapTestMeshes.h"

#include "bake/output/ImageWriters.h"
#include "bake/light/Light.h"
#include "bake/kinds/ReceiverKind.h"
#include "bake/shading/ReceiverShading.h"
#include "bake/Scene.h"
#include "receivers/LightmapReceivers.h"
#include "stream/IndexedMesh.h"

#include <catch2/catch.hpp>
#include <glm/geometric.hpp>

#include <cmath>
#include <fstream>
#include <random>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// Separating-axis test of a triangle and an axis-aligned square with positive-area overlap:
/// an independent check of the rasterizer's clipping.
bool overlaps(const glm::dvec2 (&t)[3], glm::dvec2 lo, glm::dvec2 hi) {
    auto separated = [&](glm::dvec2 axis) {
        double a0 = INFINITY, a1 = -INFINITY, b0 = INFINITY, b1 = -INFINITY;
        for (const auto& p : t) a0 = std::min(a0, glm::dot(p, axis)), a1 = std::max(a1, glm::dot(p, axis));
        for (glm::dvec2 p : {lo, hi, glm::dvec2(lo.x, hi.y), glm::dvec2(hi.x, lo.y)})
            b0 = std::min(b0, glm::dot(p, axis)), b1 = std::max(b1, glm::dot(p, axis));
        return a1 <= b0 + 1e-9 || b1 <= a0 + 1e-9;  // touching is not overlapping
    };
    if (separated({1, 0}) || separated({0, 1})) return false;
    for (int i = 0; i < 3; ++i) {
        glm::dvec2 e = t[(i + 1) % 3] - t[i];
        if (separated({-e.y, e.x})) return false;
    }
    return true;
}

IndexedMesh randomMesh(std::mt19937& rng, int triangles) {
    std::uniform_real_distribution<float> u(-0.1f, 1.1f);
    IndexedMesh mesh;
    for (int t = 0; t < 3 * triangles; ++t) {
        mesh.uv0.emplace_back(u(rng), u(rng));
        mesh.position.emplace_back(mesh.uv0.back().x, 0.f, mesh.uv0.back().y);
        mesh.indices.push_back(uint32_t(t));
    }
    return mesh;
}

std::string base64(const std::string& bytes) {
    static const char* a = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    for (size_t i = 0; i < bytes.size(); i += 3) {
        uint32_t n = uint8_t(bytes[i]) << 16;
        if (i + 1 < bytes.size()) n |= uint8_t(bytes[i + 1]) << 8;
        if (i + 2 < bytes.size()) n |= uint8_t(bytes[i + 2]);
        out += a[(n >> 18) & 63], out += a[(n >> 12) & 63];
        out += i + 1 < bytes.size() ? a[(n >> 6) & 63] : '=';
        out += i + 2 < bytes.size() ? a[n & 63] : '=';
    }
    return out;
}

/// The quad of kQuadObj as glTF (TEXCOORD_0 in glTF's top-left convention).
std::string quadGltf() {
    float pos[] = {0, 0, 0, 1, 0, 0, 1, 0, -1, 0, 0, -1};
    float nrm[] = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
    float uv[] = {0, 1, 1, 1, 1, 0, 0, 0};
    uint16_t idx[] = {0, 1, 2, 0, 2, 3};
    std::string bin(reinterpret_cast<char*>(pos), 48);
    bin += std::string(reinterpret_cast<char*>(nrm), 48) + std::string(reinterpret_cast<char*>(uv), 32) +
           std::string(reinterpret_cast<char*>(idx), 12);
    nlohmann::json g = {
        {"asset", {{"version", "2.0"}}},
        {"scenes", {{{"nodes", {0}}}}},
        {"nodes", {{{"mesh", 0}}}},
        {"meshes", {{{"name", "quad"}, {"primitives", {{{"attributes", {{"POSITION", 0}, {"NORMAL", 1}, {"TEXCOORD_0", 2}}}, {"indices", 3}}}}}}},
        {"buffers", {{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}}}},
        {"bufferViews", {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", 48}},
                         {{"buffer", 0}, {"byteOffset", 48}, {"byteLength", 48}},
                         {{"buffer", 0}, {"byteOffset", 96}, {"byteLength", 32}},
                         {{"buffer", 0}, {"byteOffset", 128}, {"byteLength", 12}}}},
        {"accessors", {{{"bufferView", 0}, {"componentType", 5126}, {"count", 4}, {"type", "VEC3"},
                        {"min", {0, 0, -1}}, {"max", {1, 0, 0}}},
                       {{"bufferView", 1}, {"componentType", 5126}, {"count", 4}, {"type", "VEC3"}},
                       {{"bufferView", 2}, {"componentType", 5126}, {"count", 4}, {"type", "VEC2"}},
                       {{"bufferView", 3}, {"componentType", 5123}, {"count", 6}, {"type", "SCALAR"}}}},
    };
    return g.dump();
}

}  // namespace

TEST_CASE("every texel a triangle's UV footprint overlaps gets a receiver", "[lightmap]") {
    std::mt19937 rng(7);
    IndexedMesh mesh = randomMesh(rng, 40);
    const int W = 37, H = 23;
    LightmapLayout layout = rasterizeLightmap(mesh, W, H);
    std::vector<int> receiverOf(size_t(W) * H, -1);
    for (size_t k = 0; k < layout.texel.size(); ++k) {
        REQUIRE(receiverOf[layout.texel[k]] == -1);  // at most one receiver per texel
        receiverOf[layout.texel[k]] = int(k);
    }
    size_t expected = 0;
    for (int y = 0; y < H; ++y) {
        for (int x = 0; x < W; ++x) {
            bool any = false, closeToEdge = false;
            for (size_t t = 0; t < mesh.triangleCount(); ++t) {
                glm::dvec2 v[3];
                for (int k = 0; k < 3; ++k) v[k] = glm::dvec2(mesh.uv0[mesh.indices[3 * t + k]]) * glm::dvec2(W, H);
                any |= overlaps(v, {x, y}, {x + 1, y + 1});
                closeToEdge |= overlaps(v, {x - 1e-6, y - 1e-6}, {x + 1 + 1e-6, y + 1 + 1e-6});
            }
            const int r = receiverOf[size_t(y) * W + x];
            if (any) {
                ++expected;
                INFO("texel " << x << "," << y);
                REQUIRE(r >= 0);
                // The receiver lies on the surface (here y = 0 and x, z = u, v) within the texel
                // or on its owning triangle's boundary next to it.
                glm::vec3 p = layout.receivers.position[size_t(r)];
                CHECK(p.y == 0.0f);
                CHECK(layout.receivers.normal[size_t(r)].y != 0.0f);
            } else if (!closeToEdge) {
                CHECK(r == -1);
            }
        }
    }
    CHECK(layout.texel.size() >= expected);
    CHECK(expected > 100);
}

TEST_CASE("receivers of a texel cut by an edge are clamped onto the triangle", "[lightmap]") {
    IndexedMesh mesh;
    mesh.uv0 = {{0.1f, 0.1f}, {0.9f, 0.1f}, {0.1f, 0.9f}};
    for (glm::vec2 uv : mesh.uv0) mesh.position.emplace_back(uv.x, uv.y, 0.f);
    mesh.indices = {0, 1, 2};
    LightmapLayout layout = rasterizeLightmap(mesh, 16, 16);
    for (size_t k = 0; k < layout.texel.size(); ++k) {
        glm::vec3 p = layout.receivers.position[k];
        CHECK(p.x >= 0.1f - 1e-6f);
        CHECK(p.y >= 0.1f - 1e-6f);
        CHECK(p.x + p.y <= 1.0f + 1e-5f);
        CHECK(layout.receivers.normal[k] == glm::vec3(0, 0, 1));  // geometric: no shading normals
        // Within the texel's reach: never more than a texel diagonal from its centre.
        glm::vec2 centre((layout.texel[k] % 16 + 0.5f) / 16, (layout.texel[k] / 16 + 0.5f) / 16);
        CHECK(glm::length(glm::vec2(p) - centre) <= std::sqrt(2.f) / 32 + 1e-6f);
    }
}

TEST_CASE("UVs far outside the unit square cost no more than the texels they reach", "[lightmap]") {
    // A damaged file's UVs: before the texel bounds were clamped ahead of their conversion to
    // int, the first triangle's bounds became INT_MIN and the loop ran over billions of texels.
    IndexedMesh mesh;
    mesh.uv0 = {{1e10f, 0.f}, {2e10f, 0.f}, {1e10f, 1.f},     // wholly right of the map: dropped
                {-1e10f, -1e10f}, {-2e10f, 0.5f}, {-1e10f, 1.f},  // wholly left and below: dropped
                {0.1f, 0.1f}, {0.9f, 0.1f}, {0.1f, 0.9f}};     // an ordinary triangle
    for (glm::vec2 uv : mesh.uv0) mesh.position.emplace_back(uv.x, uv.y, 0.f);
    mesh.indices = {0, 1, 2, 3, 4, 5, 6, 7, 8};
    IndexedMesh alone;
    alone.uv0 = {mesh.uv0.begin() + 6, mesh.uv0.end()};
    alone.position = {mesh.position.begin() + 6, mesh.position.end()};
    alone.indices = {0, 1, 2};
    const LightmapLayout layout = rasterizeLightmap(mesh, 16, 16), expected = rasterizeLightmap(alone, 16, 16);
    CHECK(layout.texel.size() > 20);
    CHECK(layout.texel == expected.texel);
    CHECK(layout.coverage == expected.coverage);
}

TEST_CASE("the surface that gets no texel is measured: UVs outside the map, no UV area", "[lightmap]") {
    IndexedMesh mesh;
    // Unit-area right triangles (world x, z), each with its own UVs.
    auto add = [&](glm::vec2 a, glm::vec2 b, glm::vec2 c, float x) {
        const uint32_t base = uint32_t(mesh.position.size());
        mesh.uv0.insert(mesh.uv0.end(), {a, b, c});
        mesh.position.insert(mesh.position.end(), {{x, 0, 0}, {x + 2, 0, 0}, {x, 0, 1}});
        mesh.indices.insert(mesh.indices.end(), {base, base + 1, base + 2});
    };
    add({0.1f, 0.1f}, {0.5f, 0.1f}, {0.1f, 0.5f}, 0);    // inside
    add({0.5f, 0.5f}, {1.5f, 0.5f}, {0.5f, 1.0f}, 3);    // a quarter of its UV area right of the map
    add({0.7f, 0.2f}, {0.7f, 0.2f}, {0.7f, 0.2f}, 6);    // collapsed to a point
    add({0.2f, 0.8f}, {0.4f, 0.8f}, {0.3f, 0.8f}, 9);    // collapsed to a line
    const LightmapLayout layout = rasterizeLightmap(mesh, 32, 32);
    CHECK(layout.surfaceArea == Approx(4.0));
    CHECK(layout.outsideArea == Approx(0.25));
    CHECK(layout.noUvArea == Approx(2.0));
    CHECK(layout.noUvTriangles == 2);
}

TEST_CASE("own UVs that leave surface unbaked are a warning, on stderr and in the stats", "[lightmap][cli]") {
    ScratchDir dir("lightmap-unbaked");
    // The quad's UVs span [-0.25, 1.25]: 56 % of it lies outside the map.
    writeText(dir / "quad.obj", "v 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\nvt -0.25 -0.25\nvt 1.25 -0.25\nvt 1.25 1.25\n"
                                "vt -0.25 1.25\nvn 0 1 0\nf 1/1/1 2/2/1 3/3/1 4/4/1\n");
    writeText(dir / "scene.json", R"({
      "geometry": [{"type": "obj", "path": "quad.obj"}],
      "lights": [{"type": "rect", "center": [0.5, 2, -0.5], "u": [1,0,0], "v": [0,0,1], "samples": 4}],
      "receivers": {"type": "lightmap", "meshes": [0], "uv": "mesh", "resolution": 16},
      "output": "out/lightmap.exr"})");
    RunResult r = runPenumbra("bake " + (dir / "scene.json") + " --quiet --stats " + (dir / "stats.json"));
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    CHECK(r.err.find("55.6 % of the surface has UVs outside [0, 1] and gets no texels") != std::string::npos);
    const nlohmann::json stats = nlohmann::json::parse(slurp(dir / "stats.json"));
    REQUIRE(stats["warnings"].size() == 1);
    CHECK(stats["warnings"][0].get<std::string>().find("outside [0, 1]") != std::string::npos);
}

TEST_CASE("padding fills the declared margin and no further", "[lightmap]") {
    const int W = 32, H = 32, rings = 3;
    std::vector<float> value(size_t(W) * H, 0.f);
    std::vector<uint8_t> filled(size_t(W) * H, 0), original;
    for (int y = 10; y < 14; ++y)
        for (int x = 12; x < 15; ++x) filled[size_t(y) * W + x] = 1, value[size_t(y) * W + x] = 2.f;
    original = filled;
    std::vector<float>* channels[] = {&value};
    dilateLightmap(channels, filled, W, H, rings);
    for (int y = 0; y < H; ++y) {
        for (int x = 0; x < W; ++x) {
            // Chebyshev distance to the filled block [12, 14] x [10, 13].
            int d = std::max({12 - x, x - 14, 10 - y, y - 13, 0});
            INFO(x << "," << y);
            CHECK(bool(filled[size_t(y) * W + x]) == (d <= rings));
            CHECK(value[size_t(y) * W + x] == (d <= rings ? 2.f : 0.f));
        }
    }
    CHECK(original != filled);
}

TEST_CASE("a unit quad lit head-on gets the analytic irradiance in every texel", "[lightmap]") {
    ScratchDir dir("lightmap");
    writeText(dir / "quad.obj", kQuadObj);
    IndexedMesh mesh = loadIndexedMeshes(dir / "quad.obj", glm::mat4(1.f)).at(0);
    LightmapLayout layout = rasterizeLightmap(mesh, 8, 8);
    REQUIRE(layout.texel.size() == 64);

    LightDesc light;  // 1 x 1, 1.5 above the quad's centre, emitting downwards
    light.center = {0.5, 1.5, -0.5}, light.u = {1, 0, 0}, light.v = {0, 0, 1};
    light.radiance = {2, 1, 0.5};
    light.samples = 1024, light.sampleSets = 1;
    LightSamples samples = generateLightSamples({light}, 64, 3);
    std::vector<uint32_t> sets(layout.texel.size(), 0);
    ReceiverResults results;
    results.resize(sets.size(), 1);
    ReceiverShader shader({light}, samples, layout.receivers, sets);
    for (uint32_t r = 0; r < sets.size(); ++r) shader.shade(r, nullptr, false, results);

    for (size_t k = 0; k < layout.texel.size(); ++k) {
        // Independent midpoint integration of cos * cos' / r^2 over the light.
        const glm::dvec3 p(layout.receivers.position[k]);
        const int n = 200;
        double integral = 0;
        for (int i = 0; i < n; ++i) {
            for (int j = 0; j < n; ++j) {
                glm::dvec3 l(light.center.x - 0.5 + (i + 0.5) / n, 1.5, light.center.z - 0.5 + (j + 0.5) / n);
                glm::dvec3 d = l - p;
                double r2 = glm::dot(d, d);
                integral += (d.y / std::sqrt(r2)) * (d.y / std::sqrt(r2)) / r2 / (double(n) * n);
            }
        }
        INFO("texel " << layout.texel[k]);
        CHECK(results.visibility[k] == 1.0f);
        CHECK(results.irradiance[k].x == Approx(2 * integral).epsilon(0.01));
        CHECK(results.irradiance[k].z == Approx(0.5 * integral).epsilon(0.01));
    }
}

TEST_CASE("overlapping UVs are counted but shared edges are not overlaps", "[lightmap]") {
    ScratchDir dir("lightmap");
    writeText(dir / "quad.obj", kQuadObj);
    IndexedMesh quad = loadIndexedMeshes(dir / "quad.obj", glm::mat4(1.f)).at(0);
    CHECK(rasterizeLightmap(quad, 16, 16).overlapping == 0);

    IndexedMesh twice = quad;  // the same quad again: every texel is covered twice...
    for (size_t i = 0; i < quad.indices.size(); ++i) twice.indices.push_back(quad.indices[i]);
    // ...except the 16 whose centres lie exactly on the quad's diagonal, inside no triangle.
    CHECK(rasterizeLightmap(twice, 16, 16).overlapping == 256 - 16);
}

TEST_CASE("OBJ and glTF of the same mesh give the same receivers", "[lightmap]") {
    ScratchDir dir("lightmap");
    writeText(dir / "quad.obj", kQuadObj);
    writeText(dir / "quad.gltf", quadGltf());
    glm::mat4 m = Transform{2.f, {0, 90, 0}, {1, 2, 3}}.matrix();
    IndexedMesh obj = loadIndexedMeshes(dir / "quad.obj", m).at(0);
    IndexedMesh gltf = loadIndexedMeshes(dir / "quad.gltf", m).at(0);
    CHECK(gltf.name == "quad");
    LightmapLayout a = rasterizeLightmap(obj, 12, 9), b = rasterizeLightmap(gltf, 12, 9);
    REQUIRE(a.texel == b.texel);
    for (size_t k = 0; k < a.texel.size(); ++k) {
        CHECK(glm::length(a.receivers.position[k] - b.receivers.position[k]) < 1e-5f);
        CHECK(glm::length(a.receivers.normal[k] - b.receivers.normal[k]) < 1e-5f);
    }
    CHECK(a.coverage == b.coverage);
}

TEST_CASE("malformed glTF never crashes the indexed mesh loader", "[lightmap]") {
    for (const auto& e : std::filesystem::recursive_directory_iterator(sharedData("gltf"))) {
        std::string ext = e.path().extension().string();
        if (!e.is_regular_file() || (ext != ".gltf" && ext != ".glb")) continue;
        try {
            loadIndexedMeshes(e.path().string(), glm::mat4(1.f));
        } catch (const InputError& error) {
            CHECK_THAT(error.what(), Catch::Contains(e.path().filename().string()));
        }
    }
}

TEST_CASE("bad lightmap parameters name the key", "[lightmap]") {
    ScratchDir dir("lightmap");
    writeText(dir / "quad.obj", kQuadObj);
    writeText(dir / "nouv.obj", "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 3 2\n");
    auto scene = [&](const std::string& receivers) {
        nlohmann::json s = nlohmann::json::parse(R"({"geometry": [{"type": "obj", "path": "quad.obj"},
            {"type": "obj", "path": "nouv.obj"}, {"type": "grid"}],
            "lights": [{"type": "rect", "center": [0,2,0], "u": [1,0,0], "v": [0,0,1]}], "receivers": )" + receivers + "}");
        return [s, &dir] { parseScene(s, dir / "scene.json"); };
    };
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "resolution": -4})")),
               Catch::Contains("receivers.resolution"));
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "resolution": [8, 0]})")),
               Catch::Contains("receivers.resolution"));
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [5]})")),
               Catch::Contains("receivers.meshes[0]") && Catch::Contains("out of range"));
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0, 1], "uv": "mesh"})")),
               Catch::Contains("receivers.meshes[1]") && Catch::Contains("texture coordinates"));
    CHECK(errorOf(scene(R"({"type": "lightmap", "meshes": [0, 1]})")) == "(no InputError thrown)");  // generated
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "uv": "xatlas"})")), Catch::Contains("receivers.uv"));
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "crease_angle_deg": 200})")),
               Catch::Contains("receivers.crease_angle_deg"));
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "chart_angle_deg": 0})")),
               Catch::Contains("receivers.chart_angle_deg"));
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "max_resolution": 0})")),
               Catch::Contains("receivers.max_resolution"));
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "power_of_two": 1})")),
               Catch::Contains("receivers.power_of_two"));
    // Keys that shape texels_per_unit's size did nothing beside a fixed resolution, silently.
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "resolution": 100, "power_of_two": true})")),
               Catch::Contains("receivers.power_of_two: applies to texels_per_unit, not to a fixed \"resolution\""));
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "resolution": 100, "max_resolution": 64})")),
               Catch::Contains("receivers.max_resolution: applies to texels_per_unit"));
    // A mesh listed twice was baked twice, the second copy as NAME-2.
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0, 0]})")),
               Catch::Contains("receivers.meshes[1]: geometry 0 is listed twice"));
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [2]})")), Catch::Contains("receivers.meshes[0]"));
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "texels_per_unit": -1})")),
               Catch::Contains("receivers.texels_per_unit"));
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "padding": -1})")),
               Catch::Contains("receivers.padding"));
    CHECK_THAT(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "colour": 1})")), Catch::Contains("receivers.colour"));
    CHECK(errorOf(scene(R"({"type": "lightmap", "meshes": [0], "texels_per_unit": 8, "resolution": null})")) ==
          "(no InputError thrown)");
}

TEST_CASE("bake writes a lightmap EXR per mesh that reads back", "[lightmap][cli]") {
    ScratchDir dir("lightmap");
    writeText(dir / "quad.obj", kQuadObj);
    writeText(dir / "scene.json", R"({
      "geometry": [{"type": "obj", "path": "quad.obj"},
                   {"type": "obj", "path": "quad.obj", "transform": {"scale": 0.3, "translate": [0.35, 0.5, 0]}}],
      "lights": [{"type": "rect", "center": [0.5, 2, -0.5], "u": [1,0,0], "v": [0,0,1], "samples": 64, "sample_sets": 2}],
      "receivers": {"type": "lightmap", "meshes": [0], "resolution": [16, 12], "padding": 2},
      "output": "out/lightmap.exr"})");
    RunResult r = runPenumbra("bake " + (dir / "scene.json") + " --quiet");
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    ExrImage img = readExr(dir / "out/lightmap-quad.exr");
    CHECK(img.width == 16);
    CHECK(img.height == 12);
    CHECK(img.channels.size() == 5);
    for (const char* channel : {"R", "G", "B", "A", "visibility.V"}) CHECK(img.channels.count(channel));
    CHECK(img.attribute<std::string>("penumbra:receivers") == "lightmap");
    CHECK(img.attribute<int>("penumbra:samples") == 64);
    CHECK(img.attribute<int>("penumbra:padding") == 2);
    CHECK(img.attribute<int>("penumbra:texels") == 16 * 12);
    float lo = 1, hi = 0;
    for (float v : img.channels["visibility.V"]) lo = std::min(lo, v), hi = std::max(hi, v);
    CHECK(lo < 0.5f);   // the small quad above shadows part of the big one
    CHECK(hi == 1.0f);
    for (float a : img.channels["A"]) CHECK(a == Approx(1.0f));  // the quad covers the whole map
    CHECK(std::filesystem::file_size(dir / "out/lightmap-quad.png") > 50);
}
