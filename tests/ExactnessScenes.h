#pragma once
// The exactness scenes every exact method is checked on against the reference (hpc in
// test_hpc_exactness.cpp, ssv in test_ssv_caster.cpp): blockers, receivers and lights.

#include "TestScenes.h"

#include "procedural/BoxesGenerator.h"
#include "procedural/GridGenerator.h"

#include <string>
#include <utility>
#include <vector>

namespace penumbra::test {

/// One scene: its triangles and receivers, and the lights it is cast with.
struct ExactScene {
    std::vector<Triangle> triangles;
    ReceiverSet receivers;
    std::vector<std::pair<std::string, LightDesc>> lights;  ///< each cast on its own
};

/// Random triangles over a floor, receivers in the air, on the floor and on the blockers.
inline ExactScene soupScene(uint64_t seed) {
    ExactScene s;
    s.triangles = triangleSoup(seed, 60, {-2, 1, -2}, {2, 3, 2}, 1.2f);
    std::vector<Triangle> floor = floorQuad(4);
    s.receivers = randomReceivers(seed + 10, 300, {-3, -0.5f, -3}, {3, 2.5f, 3});
    addReceiversOnTriangles(s.receivers, floor, seed, 150);
    addReceiversOnTriangles(s.receivers, s.triangles, seed + 20, 2);
    s.triangles.insert(s.triangles.end(), floor.begin(), floor.end());
    s.lights = {{"soup " + std::to_string(seed), rectLight({0, 5, 0}, {2, 0, 0}, {0, 0, 1.5}, 128, 4)}};
    return s;
}

/// Three stacked perforated grids over a floor (the paper's GRIDS, small).
inline ExactScene stackedGridsScene() {
    ExactScene s;
    GridParams p;
    p.cells = 5, p.levels = 3, p.size = 3, p.floorSize = 6;
    s.triangles = readAll(*makeGridSource(p));
    addReceiversOnTriangles(s.receivers, std::vector<Triangle>(s.triangles.begin(), s.triangles.begin() + 2), 5, 400);
    addReceiversOnTriangles(s.receivers, std::vector<Triangle>(s.triangles.begin() + 2, s.triangles.begin() + 200), 6, 1);
    s.lights = {{"grids", rectLight({0.3, 4, 0.2}, {1.5, 0, 0}, {0, 0, 1.5}, 256, 8)}};
    return s;
}

/// spot.obj (closed) shadowing itself and a floor.
inline ExactScene spotScene() {
    ExactScene s;
    s.triangles = spotMesh();
    std::vector<Triangle> floor = floorQuad(3);
    addReceiversOnTriangles(s.receivers, floor, 9, 200);
    addReceiversOnTriangles(s.receivers, everyNth(s.triangles, 40), 10, 1);
    s.triangles.insert(s.triangles.end(), floor.begin(), floor.end());
    s.lights = {{"spot", rectLight({0.5, 4, 0.5}, {1.5, 0, 0}, {0, 0.3, 1.2}, 64, 4)}};
    return s;
}

/// spot.obj and boxes marked closed, standing under, beside and above the lights' level, so each
/// light sees some of their faces from behind only.
inline ExactScene closedSolidsScene() {
    ExactScene s;
    s.triangles = spotMesh();
    for (Triangle& t : s.triangles) t.flags = kTriangleClosed;
    const std::vector<BoxShape> boxes = {
        {{-2.5, 0.2, -0.5}, {-1.5, 0.6, 0.5}}, {{1.6, 0.5, 1.0}, {2.2, 2.5, 1.4}}, {{-0.4, 2.6, -2.4}, {0.4, 2.8, -1.6}}};
    const std::vector<Triangle> solids = readAll(*makeBoxSource(boxes));
    s.triangles.insert(s.triangles.end(), solids.begin(), solids.end());
    std::vector<Triangle> floor = floorQuad(3.5f);
    addReceiversOnTriangles(s.receivers, floor, 9, 300);
    addReceiversOnTriangles(s.receivers, everyNth(s.triangles, 30), 10, 1);
    addReceiversOnTriangles(s.receivers, solids, 11, 4);
    s.triangles.insert(s.triangles.end(), floor.begin(), floor.end());
    s.lights = {{"closed, rect above", rectLight({0.5, 4, 0.5}, {1.5, 0, 0}, {0, 0.3, 1.2}, 64, 4)},
                {"closed, tilted rect at the side", rectLight({4, 1.5, 0}, {0, 1, 0.2}, {0.1, 0, 1}, 64, 4)},
                {"closed, sphere", sphereLight()}};
    return s;
}

/// Slivers, a zero-area triangle and receivers hugging edges.
inline ExactScene sliversScene() {
    ExactScene s;
    Rng rng(42);
    for (int i = 0; i < 60; ++i) {
        glm::vec3 a = randomIn(rng, {-2, 1, -2}, {2, 2.5f, 2});
        glm::vec3 b = a + randomIn(rng, {-2, -0.2f, -2}, {2, 0.2f, 2});
        float t = float(rng.uniform());
        glm::vec3 c = a + t * (b - a) + glm::vec3(0, float(1e-4 * rng.uniform()), float(1e-5 * rng.uniform()));
        s.triangles.push_back({{a, b, c}, 0});
    }
    s.triangles.push_back({{glm::vec3(0, 1, 0), glm::vec3(1, 1, 0), glm::vec3(2, 1, 0)}, 0});  // zero area: blocks nothing
    std::vector<Triangle> floor = floorQuad(3);
    addReceiversOnTriangles(s.receivers, floor, 3, 300);
    addReceiversOnTriangles(s.receivers, s.triangles, 4, 3);
    s.triangles.insert(s.triangles.end(), floor.begin(), floor.end());
    s.lights = {{"slivers", rectLight({0, 4, 0}, {1, 0, 0}, {0, 0, 1}, 64, 4)}};
    return s;
}

/// Blockers straddling and touching the light's plane (y = 3), receivers above and below it.
inline ExactScene straddlingScene() {
    ExactScene s;
    s.triangles = triangleSoup(77, 40, {-2, 2.5f, -2}, {2, 3.5f, 2}, 1.5f);
    s.triangles.push_back({{glm::vec3(-0.2f, 3, -0.2f), glm::vec3(0.3f, 2.5f, 0), glm::vec3(0, 3.5f, 0.3f)}, 0});
    std::vector<Triangle> floor = floorQuad(3);
    s.receivers = randomReceivers(78, 300, {-3, -0.2f, -3}, {3, 4.5f, 3});
    addReceiversOnTriangles(s.receivers, floor, 79, 200);
    s.triangles.insert(s.triangles.end(), floor.begin(), floor.end());
    s.lights = {{"straddling", rectLight({0, 3, 0}, {1.5, 0, 0}, {0, 0.4, 1.5}, 64, 4)}};
    return s;
}

/// A disk and a rect light @p sizes scene sizes (8 units) away, about 3.4 degrees across.
inline std::vector<LightDesc> farLights(double sizes) {
    const glm::dvec3 towards = glm::normalize(glm::dvec3(0.3, 1, 0.2));
    const double distance = 8 * sizes, radius = distance * 0.03;
    LightDesc disk;
    disk.type = LightType::Disk, disk.center = distance * towards, disk.normal = -towards, disk.radius = radius;
    disk.samples = 64, disk.sampleSets = 4, disk.where = "disk";
    const glm::dvec3 u = glm::normalize(glm::cross(towards, glm::dvec3(0, 0, 1))), v = glm::cross(towards, u);
    LightDesc rect = rectLight(distance * towards, 2 * radius * v, 2 * radius * u, 64, 4);
    rect.where = "rect";
    return {disk, rect};
}

}  // namespace penumbra::test
