// Camera outputs: smooth coherent shading keeps light off faces turned away from it, and a camera
// bake with several lights writes per-light EXR layers and light/sample attributes.

#include "TestScenes.h"

#include "bake/kinds/CameraOutput.h"
#include "bake/output/ImageWriters.h"
#include "bake/Pipeline.h"
#include "bake/shading/ReceiverShading.h"
#include "bake/Scene.h"
#include "bake/shading/SmoothShading.h"
#include "receivers/CameraReceivers.h"

#include <catch2/catch.hpp>

#include <glm/geometric.hpp>

#include <fstream>
#include <map>
#include <numeric>
#include <random>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// A unit icosphere (outward winding), subdivided @p levels times.
std::vector<Triangle> icosphere(int levels, glm::vec3 center, float radius) {
    const float t = (1.f + std::sqrt(5.f)) / 2.f;
    std::vector<glm::vec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    for (auto& p : v) p = glm::normalize(p);
    std::vector<glm::ivec3> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8},   {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                                 {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (int l = 0; l < levels; ++l) {
        std::map<std::pair<int, int>, int> mid;
        auto midpoint = [&](int a, int b) {
            auto key = std::minmax(a, b);
            auto it = mid.find(key);
            if (it != mid.end()) return it->second;
            v.push_back(glm::normalize(v[a] + v[b]));
            return mid[key] = int(v.size()) - 1;
        };
        std::vector<glm::ivec3> next;
        for (auto tri : f) {
            int a = midpoint(tri.x, tri.y), b = midpoint(tri.y, tri.z), c = midpoint(tri.z, tri.x);
            next.insert(next.end(), {{tri.x, a, c}, {tri.y, b, a}, {tri.z, c, b}, {a, b, c}});
        }
        f = next;
    }
    std::vector<Triangle> out;
    for (auto tri : f) out.push_back({{center + radius * v[tri.x], center + radius * v[tri.y], center + radius * v[tri.z]}, 0});
    return out;
}

}  // namespace

TEST_CASE("smooth shading leaves no energy on faces turned away from the light", "[shading][camera]") {
    // A large rect light at the side: its far edge still reaches faces whose normals point away
    // from its centre, which is the leak smooth coherent shading removes.
    std::vector<Triangle> sphere = icosphere(1, {0, 0, 0}, 1.f);
    LightDesc light = rectLight({4, 0, 0}, {0, 0, 6}, {0, 6, 0}, 256, 1);  // u x v = -x: faces the sphere
    CameraDesc cam;
    cam.eye = {0, 0.5, 5}, cam.target = {0, 0, 0}, cam.width = 96, cam.height = 96, cam.fovDeg = 35;
    CameraRasterizer raster(cam);
    raster.recordTriangles();
    raster.add(sphere);
    ReceiverSet receivers = raster.finish();
    REQUIRE(receivers.size() > 1000);
    VertexBend bend(raster.takeTriangles(), receivers.normal, lightDirections({light}));
    bend.add(sphere);

    LightSamples samples = generateLightSamples({light}, 64, 3);
    std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    ReceiverShader shader({light}, samples, receivers, sets);
    ReceiverResults results;
    results.resize(receivers.size(), 1);
    for (uint32_t r = 0; r < receivers.size(); ++r) shader.shade(r, nullptr, false, results);

    double leak = 0;
    int backFacing = 0, kept = 0;
    for (size_t r = 0; r < receivers.size(); ++r) {
        glm::dvec3 p(receivers.position[r]), n(receivers.normal[r]);
        glm::dvec3 l = glm::normalize(light.center - p);
        glm::vec3 smooth = shadedIrradiance(receivers, results, r, &bend);
        if (glm::dot(n, l) <= 0) {
            ++backFacing;
            leak += results.irradiance[r].x;
            CHECK(smooth.x == 0.f);
        } else if (glm::dot(n, l) > 0.6) {  // well inside the lit side: unchanged
            kept += smooth.x == Approx(results.irradiance[r].x);
        }
        CHECK(smooth.x <= results.irradiance[r].x * 1.000001f);
    }
    CHECK(backFacing > 100);
    CHECK(leak > 0);  // without smooth shading the back faces do get light
    CHECK(kept > 50);
}

TEST_CASE("a camera bake with two lights writes per-light layers and light attributes", "[camera][radiometry]") {
    ScratchDir dir("camera");
    {
        std::ofstream obj(dir / "scene.obj");
        obj << "v -3 0 -3\nv 3 0 -3\nv 3 0 3\nv -3 0 3\nf 1 3 2\nf 1 4 3\n";  // floor, facing up
        obj << "v -0.5 1 -0.5\nv 0.5 1 -0.5\nv 0.5 1 0.5\nv -0.5 1 0.5\nf 5 7 6\nf 5 8 7\n";  // a blocker
    }
    nlohmann::json scene = {
        {"geometry", {{{"type", "obj"}, {"path", "scene.obj"}}}},
        {"lights",
         {{{"type", "rect"}, {"center", {0, 3, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}, {"power", 10}, {"samples", 64}},
          {{"type", "sun"}, {"direction", {-0.3, -1, 0.1}}, {"irradiance", {100, 90, 80}}, {"samples", 64}}}},
        {"receivers", {{"type", "camera"}, {"eye", {0, 6, 4}}, {"target", {0, 0, 0}}, {"width", 40}, {"height", 30}}},
        {"output", "out/cam.exr"},
        {"bake", {{"smooth_shading", true}}},
    };
    registerFileSourceTypes();
    SceneDesc desc = parseScene(scene, dir / "scene.json");
    BakeSettings settings;
    settings.quiet = true;
    runBake(desc, settings);
    ExrImage img = readExr(dir / "out/cam.exr");
    for (const char* c : {"visibility.V", "A", "depth.Z", "R", "G", "B", "normal.X", "normal.Y", "normal.Z",
                          "light0.visibility.V", "light0.irradiance.R", "light0.irradiance.G", "light0.irradiance.B",
                          "light1.visibility.V", "light1.irradiance.R", "light1.irradiance.G", "light1.irradiance.B"})
        CHECK(img.channels.count(c) == 1);
    CHECK(img.attribute<int>("penumbra:lights") == 2);
    CHECK(img.attribute<std::string>("penumbra:light1.type") == "sun");
    CHECK(img.attribute<glm::vec3>("penumbra:light1.irradiance") == glm::vec3(100, 90, 80));
    CHECK(img.attribute<glm::vec3>("penumbra:light0.center") == glm::vec3(0, 3, 0));
    CHECK(img.attribute<float>("penumbra:light0.area") == 1.f);
    // 10 W from 1 m^2, one-sided Lambertian: L = P / (pi A).
    CHECK(img.attribute<glm::vec3>("penumbra:light0.radiance").x == Approx(10 / M_PI));
    CHECK(std::filesystem::exists(dir / "out/cam.png"));
    int shadowed = 0;
    for (size_t px = 0; px < img.channels["visibility.V"].size(); ++px) {
        if (img.channels["A"][px] == 0) continue;
        float sumE = img.channels["light0.irradiance.R"][px] + img.channels["light1.irradiance.R"][px];
        CHECK(sumE == Approx(img.channels["R"][px]).epsilon(1e-4).margin(1e-4));
        // V counts all samples: equal counts per light, so it is the mean of the two.
        CHECK(0.5f * (img.channels["light0.visibility.V"][px] + img.channels["light1.visibility.V"][px]) ==
              Approx(img.channels["visibility.V"][px]));
        shadowed += img.channels["light1.visibility.V"][px] < 1;
    }
    CHECK(shadowed > 0);
}

TEST_CASE("a deep camera keeps the nearest distinct surfaces per pixel as extra EXR layers", "[camera]") {
    // Three parallel quads facing the camera at z = 0, -1, -2, viewed head-on.
    std::vector<Triangle> tris;
    for (float z : {0.f, -1.f, -2.f}) addQuad(tris, {-5, -5, z}, {5, -5, z}, {5, 5, z}, {-5, 5, z});
    tris.push_back(tris[0]);  // the same surface again is not a new layer
    CameraDesc cam;
    cam.eye = {0, 0, 5}, cam.target = {0, 0, 0}, cam.width = 8, cam.height = 6, cam.layers = 2;
    CameraRasterizer raster(cam);
    raster.add(tris);
    ReceiverSet r = raster.finish();
    REQUIRE(r.size() == 2 * 48);
    for (size_t i = 0; i < r.size(); ++i) {
        const bool second = r.pixel[i] >= 48;
        CHECK(r.position[i].z == Approx(second ? -1.f : 0.f).margin(1e-5));
    }
    ScratchDir dir("deep");
    SceneDesc scene;
    scene.lights = {rectLight({0, 0, 4}, {1, 0, 0}, {0, 1, 0}, 16, 1)};
    LightSamples samples = generateLightSamples(scene.lights, 64, 1);
    ReceiverResults results;
    results.resize(r.size(), 1);
    for (size_t i = 0; i < r.size(); ++i) results.visibility[i] = i < 48 ? 1.f : 0.25f;
    writeCameraOutputs(scene, cam, r, samples, results, dir / "deep.exr");
    ExrImage img = readExr(dir / "deep.exr");
    for (const char* c : {"layer1.Combined.R", "layer1.Combined.G", "layer1.Combined.B", "layer1.Combined.A",
                          "layer1.visibility.V", "layer1.depth.Z", "layer1.normal.X", "layer1.normal.Y", "layer1.normal.Z"})
        REQUIRE(img.channels.count(c) == 1);
    CHECK(img.channels.size() == 18);
    CHECK(img.channels.count("layer2.visibility.V") == 0);
    CHECK(img.channels["visibility.V"][10] == 1.f);
    CHECK(img.channels["layer1.visibility.V"][10] == 0.25f);
    CHECK(img.channels["layer1.Combined.A"][10] == 1.f);
    // Head-on quads at z = 0 and -1 from an eye at z = 5: view depths 5 and 6 at every pixel.
    CHECK(img.channels["depth.Z"][10] == Approx(5.f));
    CHECK(img.channels["layer1.depth.Z"][10] == Approx(6.f));
    CameraDesc bad = cam;
    bad.layers = 17;
    CHECK_THROWS_WITH(validateCamera(bad), Catch::Contains("layers"));
}

TEST_CASE("smooth shading finds the same vertices from triangle ids as from the triangles", "[shading][camera]") {
    // Two icospheres seen from outside and a floor seen from below (its winding faces away, so
    // its receivers carry the flipped bit): many receivers share each triangle, and recover()
    // reuses a triangle's slots for its neighbours in the id order. Read through the stream in
    // chunks of 97, the ids give the same slots, so every factor is the same bits as the table
    // built from the triangles themselves.
    std::vector<Triangle> scene = icosphere(2, {0, 0, 0}, 1.f);
    const std::vector<Triangle> second = icosphere(1, {1.6f, 0.3f, -0.5f}, 0.7f);
    scene.insert(scene.end(), second.begin(), second.end());
    scene.push_back({{glm::vec3(-4, -1.2f, -4), glm::vec3(4, -1.2f, -4), glm::vec3(4, -1.2f, 4)}, 0});  // faces down
    scene.push_back({{glm::vec3(-4, -1.2f, -4), glm::vec3(4, -1.2f, 4), glm::vec3(-4, -1.2f, 4)}, 0});
    const LightDesc light = rectLight({3, 4, 2}, {2, 0, 0}, {0, 0, 2}, 64, 1);
    CameraDesc cam;
    cam.eye = {0.5, -0.2, 5}, cam.target = {0, -0.5, 0}, cam.width = 80, cam.height = 60, cam.fovDeg = 60;
    CameraRasterizer raster(cam);
    raster.recordTriangles();
    raster.recordTriangleIds();
    raster.add(scene);
    const ReceiverSet receivers = raster.finish();
    const std::vector<uint64_t> ids = raster.takeTriangleIds();
    REQUIRE(receivers.size() > 2000);
    REQUIRE(std::count_if(ids.begin(), ids.end(), [](uint64_t id) { return id & CameraRasterizer::kFlippedBit; }) > 100);

    VertexBend fromTriangles(raster.takeTriangles(), receivers.normal, lightDirections({light}));
    VertexBend fromIds(lightDirections({light}));
    fromIds.expectTriangleIds(ids);
    for (size_t at = 0; at < scene.size(); at += 97)
        fromIds.recover(std::span<const Triangle>(scene).subspan(at, std::min<size_t>(97, scene.size() - at)));
    fromTriangles.add(scene);
    fromIds.add(scene);
    CHECK(fromIds.vertices() == fromTriangles.vertices());
    int bent = 0;
    for (size_t r = 0; r < receivers.size(); ++r) {
        const glm::dvec3 p(receivers.position[r]), n(receivers.normal[r]);
        const double f = fromTriangles.factor(r, p, n, 0);
        CHECK(fromIds.factor(r, p, n, 0) == f);
        bent += f < 1.0;
    }
    CHECK(bent > 100);
}

TEST_CASE("receivers are put in triangle order for the id recovery, equal ids in receiver order", "[shading][camera]") {
    // The radix passes cover the largest id's bits: ids past 2^22 and 2^33 take three and four,
    // and the flip bit is no part of the order.
    std::mt19937_64 rng(9);
    for (const uint64_t range : {uint64_t(7), uint64_t(5000), uint64_t(1) << 23, uint64_t(1) << 34}) {
        std::vector<uint64_t> ids(20000);
        for (uint64_t& id : ids) id = (rng() % range) | (rng() % 3 == 0 ? CameraRasterizer::kFlippedBit : 0);
        std::vector<uint32_t> expected(ids.size());
        std::iota(expected.begin(), expected.end(), 0u);
        const uint64_t mask = ~CameraRasterizer::kFlippedBit;
        std::stable_sort(expected.begin(), expected.end(), [&](uint32_t a, uint32_t b) { return (ids[a] & mask) < (ids[b] & mask); });
        CHECK(VertexBend::sortedByTriangle(ids) == expected);
    }
    CHECK(VertexBend::sortedByTriangle({}).empty());
}
