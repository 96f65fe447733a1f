// Exactness: hierarchical penumbra casting, with every optimization on, off, or singly off,
// gives masks bit-identical to plain ray casting under the same blocking rule.

#include "ExactnessScenes.h"
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

void requireSceneMatchesReference(const ExactScene& s) {
    for (const auto& [name, light] : s.lights) requireMatchesReference(name, {light}, s.receivers, s.triangles);
}

}  // namespace

TEST_CASE("random triangle soups match the reference", "[hpc][exact]") {
    for (uint64_t seed : {1, 2, 3}) requireSceneMatchesReference(soupScene(seed));
}

TEST_CASE("stacked perforated grids match the reference", "[hpc][exact]") { requireSceneMatchesReference(stackedGridsScene()); }

TEST_CASE("a closed mesh (spot.obj) shadowing itself and a floor matches the reference", "[hpc][exact]") {
    requireSceneMatchesReference(spotScene());
}

TEST_CASE("closed casters: skipping back faces of closed solids keeps the reference's masks", "[hpc][exact][closed]") {
    const ExactScene s = closedSolidsScene();
    for (const auto& [name, light] : s.lights) {
        requireMatchesReference(name, {light}, s.receivers, s.triangles);
        LightSamples samples = generateLightSamples({light}, 64, 7);
        CastStats stats;
        castHpc(samples, s.receivers, assignSets(s.receivers, samples.sets), s.triangles, CastOptions(), 1, 97, &stats);
        INFO(name);
        CHECK(stats.closedBackFaces > 500);  // about half of spot faces away from any light
    }
}

TEST_CASE("slivers, near-degenerate triangles and receivers on edges match the reference", "[hpc][exact]") {
    requireSceneMatchesReference(sliversScene());
}

TEST_CASE("blockers straddling and touching the light's plane match the reference", "[hpc][exact]") {
    requireSceneMatchesReference(straddlingScene());
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
