// Exactness: hierarchical penumbra casting, with every optimization on, off, or singly off,
// gives masks bit-identical to plain ray casting under the same blocking rule.

#include "TestScenes.h"

#include "bake/peers/ReferenceCaster.h"
#include "procedural/BoxesGenerator.h"
#include "procedural/GridGenerator.h"
#include "stream/ObjReader.h"
#include "stream/Transform.h"

#include <catch2/catch.hpp>

using namespace penumbra;
using namespace penumbra::test;

namespace {

std::vector<Triangle> floorQuad(float half, float y = 0.f) {
    std::vector<Triangle> t;
    addQuad(t, {-half, y, -half}, {half, y, -half}, {half, y, half}, {-half, y, half});
    return t;
}

/// spot.obj (watertight, wound outward) standing one unit above the origin.
std::vector<Triangle> spotMesh() {
    Transform place;
    place.translate = {0, 1.0f, 0};
    TransformedSource spot(openObj(sharedData("meshes/spot.obj")), place.matrix());
    std::vector<Triangle> mesh = readAll(spot);
    REQUIRE(mesh.size() == 5856);
    return mesh;
}

std::vector<Triangle> everyNth(const std::vector<Triangle>& tris, size_t n) {
    std::vector<Triangle> some;
    for (size_t i = 0; i < tris.size(); i += n) some.push_back(tris[i]);
    return some;
}

}  // namespace

TEST_CASE("random triangle soups match the reference", "[hpc][exact]") {
    for (uint64_t seed : {1, 2, 3}) {
        std::vector<Triangle> tris = triangleSoup(seed, 60, {-2, 1, -2}, {2, 3, 2}, 1.2f);
        std::vector<Triangle> floor = floorQuad(4);
        ReceiverSet receivers = randomReceivers(seed + 10, 300, {-3, -0.5f, -3}, {3, 2.5f, 3});
        addReceiversOnTriangles(receivers, floor, seed, 150);
        addReceiversOnTriangles(receivers, tris, seed + 20, 2);
        tris.insert(tris.end(), floor.begin(), floor.end());
        requireMatchesReference("soup " + std::to_string(seed), {rectLight({0, 5, 0}, {2, 0, 0}, {0, 0, 1.5}, 128, 4)}, receivers, tris);
    }
}

TEST_CASE("stacked perforated grids match the reference", "[hpc][exact]") {
    GridParams p;
    p.cells = 5, p.levels = 3, p.size = 3, p.floorSize = 6;
    std::vector<Triangle> tris = readAll(*makeGridSource(p));
    ReceiverSet receivers;
    addReceiversOnTriangles(receivers, std::vector<Triangle>(tris.begin(), tris.begin() + 2), 5, 400);
    addReceiversOnTriangles(receivers, std::vector<Triangle>(tris.begin() + 2, tris.begin() + 200), 6, 1);
    requireMatchesReference("grids", {rectLight({0.3, 4, 0.2}, {1.5, 0, 0}, {0, 0, 1.5}, 256, 8)}, receivers, tris);
}

TEST_CASE("a closed mesh (spot.obj) shadowing itself and a floor matches the reference", "[hpc][exact]") {
    std::vector<Triangle> mesh = spotMesh();
    std::vector<Triangle> floor = floorQuad(3);
    ReceiverSet receivers;
    addReceiversOnTriangles(receivers, floor, 9, 200);
    addReceiversOnTriangles(receivers, everyNth(mesh, 40), 10, 1);
    mesh.insert(mesh.end(), floor.begin(), floor.end());
    requireMatchesReference("spot", {rectLight({0.5, 4, 0.5}, {1.5, 0, 0}, {0, 0.3, 1.2}, 64, 4)}, receivers, mesh);
}

TEST_CASE("closed casters: skipping back faces of closed solids keeps the reference's masks", "[hpc][exact][closed]") {
    // spot.obj is watertight and wound outward; boxes stand under, beside and above the light's
    // level, so each light sees some of their faces from behind only.
    std::vector<Triangle> tris = spotMesh();
    for (Triangle& t : tris) t.flags = kTriangleClosed;
    const std::vector<BoxShape> boxes = {
        {{-2.5, 0.2, -0.5}, {-1.5, 0.6, 0.5}}, {{1.6, 0.5, 1.0}, {2.2, 2.5, 1.4}}, {{-0.4, 2.6, -2.4}, {0.4, 2.8, -1.6}}};
    const std::vector<Triangle> solids = readAll(*makeBoxSource(boxes));
    tris.insert(tris.end(), solids.begin(), solids.end());
    std::vector<Triangle> floor = floorQuad(3.5f);
    ReceiverSet receivers;
    addReceiversOnTriangles(receivers, floor, 9, 300);
    addReceiversOnTriangles(receivers, everyNth(tris, 30), 10, 1);
    addReceiversOnTriangles(receivers, solids, 11, 4);
    tris.insert(tris.end(), floor.begin(), floor.end());

    const std::vector<std::pair<std::string, LightDesc>> lights = {
        {"rect above", rectLight({0.5, 4, 0.5}, {1.5, 0, 0}, {0, 0.3, 1.2}, 64, 4)},
        {"tilted rect at the side", rectLight({4, 1.5, 0}, {0, 1, 0.2}, {0.1, 0, 1}, 64, 4)},
        {"sphere", sphereLight()}};
    for (const auto& [name, light] : lights) {
        requireMatchesReference("closed, " + name, {light}, receivers, tris);
        LightSamples samples = generateLightSamples({light}, 64, 7);
        CastStats stats;
        castHpc(samples, receivers, assignSets(receivers, samples.sets), tris, CastOptions(), 1, 97, &stats);
        INFO(name);
        CHECK(stats.closedBackFaces > 500);  // about half of spot faces away from any light
    }
}

TEST_CASE("slivers, near-degenerate triangles and receivers on edges match the reference", "[hpc][exact]") {
    Rng rng(42);
    std::vector<Triangle> tris;
    for (int i = 0; i < 60; ++i) {
        glm::vec3 a = randomIn(rng, {-2, 1, -2}, {2, 2.5f, 2});
        glm::vec3 b = a + randomIn(rng, {-2, -0.2f, -2}, {2, 0.2f, 2});
        float t = float(rng.uniform());
        glm::vec3 c = a + t * (b - a) + glm::vec3(0, float(1e-4 * rng.uniform()), float(1e-5 * rng.uniform()));
        tris.push_back({{a, b, c}, 0});
    }
    tris.push_back({{glm::vec3(0, 1, 0), glm::vec3(1, 1, 0), glm::vec3(2, 1, 0)}, 0});  // zero area: blocks nothing
    std::vector<Triangle> floor = floorQuad(3);
    ReceiverSet receivers;
    addReceiversOnTriangles(receivers, floor, 3, 300);
    addReceiversOnTriangles(receivers, tris, 4, 3);
    tris.insert(tris.end(), floor.begin(), floor.end());
    requireMatchesReference("slivers", {rectLight({0, 4, 0}, {1, 0, 0}, {0, 0, 1}, 64, 4)}, receivers, tris);
}

TEST_CASE("blockers straddling and touching the light's plane match the reference", "[hpc][exact]") {
    std::vector<Triangle> tris = triangleSoup(77, 40, {-2, 2.5f, -2}, {2, 3.5f, 2}, 1.5f);  // light at y=3
    tris.push_back({{glm::vec3(-0.2f, 3, -0.2f), glm::vec3(0.3f, 2.5f, 0), glm::vec3(0, 3.5f, 0.3f)}, 0});  // through the light
    std::vector<Triangle> floor = floorQuad(3);
    ReceiverSet receivers = randomReceivers(78, 300, {-3, -0.2f, -3}, {3, 4.5f, 3});
    addReceiversOnTriangles(receivers, floor, 79, 200);
    tris.insert(tris.end(), floor.begin(), floor.end());
    requireMatchesReference("straddling", {rectLight({0, 3, 0}, {1.5, 0, 0}, {0, 0.4, 1.5}, 64, 4)}, receivers, tris);
}

TEST_CASE("every light type, alone and together, matches the reference", "[hpc][exact]") {
    std::vector<Triangle> tris;
    ReceiverSet receivers;
    soupOverFloor(tris, receivers);
    const LightDesc disk = diskLight(), sphere = sphereLight(), polygon = polygonLight();
    LightDesc rect = rectLight({0, 4, 0}, {1.3, 0.2, 0}, {0, 0.1, 1.1}, 64, 4);

    requireMatchesReference("disk", {disk}, receivers, tris);
    requireMatchesReference("sphere", {sphere}, receivers, tris);
    requireMatchesReference("polygon", {polygon}, receivers, tris);
    requireMatchesReference("rect, groups of 17", {rect}, receivers, tris, 17);
    requireMatchesReference("all four lights", {rect, disk, sphere, polygon}, receivers, tris, 32);
}
