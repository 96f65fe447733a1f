// Soft shadow volumes with frustum shooting (--method ssv): the same masks as the reference on
// the exactness scenes the other methods use, up to classified ties.

#include "ExactnessScenes.h"
#include "MethodChecks.h"
#include "TestScenes.h"

#include "procedural/BoxesGenerator.h"

#include <catch2/catch.hpp>

using namespace penumbra;
using namespace penumbra::test;

namespace {

void requireSceneMatches(const ExactScene& s) {
    for (const auto& [name, light] : s.lights) requireSsvMatchesReference(name, {light}, s.receivers, s.triangles);
}

}  // namespace

TEST_CASE("ssv: the exactness scenes match the reference", "[ssv][exact]") {
    // The scenes of test_hpc_exactness.cpp: soups, stacked perforated grids, a closed mesh
    // (spot.obj) shadowing itself and a floor, closed solids lit from above, the side and a
    // sphere, slivers and receivers on edges, blockers straddling the light's plane.
    for (uint64_t seed : {1, 2, 3}) {
        INFO("soup " << seed);
        requireSceneMatches(soupScene(seed));
    }
    const std::pair<const char*, ExactScene (*)()> scenes[] = {
        {"stacked grids", &stackedGridsScene}, {"spot.obj", &spotScene},   {"closed solids", &closedSolidsScene},
        {"slivers", &sliversScene},            {"straddling", &straddlingScene},
    };
    for (const auto& [name, make] : scenes) {
        INFO(name);
        requireSceneMatches(make());
    }
}

TEST_CASE("ssv: every light type, alone and together, matches the reference", "[ssv][exact]") {
    std::vector<Triangle> tris;
    ReceiverSet receivers;
    soupOverFloor(tris, receivers);
    LightDesc rect = rectLight({0, 4, 0}, {1.3, 0.2, 0}, {0, 0.1, 1.1}, 64, 4);
    requireSsvMatchesReference("disk", {diskLight()}, receivers, tris);
    requireSsvMatchesReference("sphere", {sphereLight()}, receivers, tris);
    requireSsvMatchesReference("polygon", {polygonLight()}, receivers, tris);
    requireSsvMatchesReference("rect, groups of 17", {rect}, receivers, tris, 17);
    requireSsvMatchesReference("all four lights", {rect, diskLight(), sphereLight(), polygonLight()}, receivers, tris, 32);
}

TEST_CASE("ssv: suns on grass and on boxes match the reference", "[ssv][exact][sun]") {
    for (int scene = 0; scene < 2; ++scene) {
        std::vector<Triangle> tris;
        ReceiverSet receivers;
        if (scene == 0) grassScene(tris, receivers, 120);
        else boxesScene(tris, receivers);
        requireSsvMatchesReference(scene == 0 ? "grass" : "boxes", {sunLight({0.45, -1, 0.3}, scene == 0 ? 0.53 : 4.0, 64)},
                                   receivers, tris);
    }
}

TEST_CASE("ssv: disk and rect lights 1e2, 1e4 and 4e5 scene sizes away match the reference", "[ssv][exact][far]") {
    std::vector<Triangle> tris;
    ReceiverSet receivers;
    soupOverFloor(tris, receivers);
    for (double sizes : {1e2, 1e4, 4e5}) {
        for (const LightDesc& light : farLights(sizes)) {
            INFO(sizes << " scene sizes away, " << light.where);
            requireSsvMatchesReference("far", {light}, receivers, tris);
        }
    }
}

TEST_CASE("ssv: a receiver in the band behind a box's top, near an edge lit at a grazing angle", "[ssv][exact][band]") {
    // The box's top and its side facing the light both face the light, so their shared edge is
    // no potential silhouette. Receivers lie 6e-6 below the top (inside the rule's band of 1e-5,
    // so the top does not block them) and just inside the side: rays that pass under the edge
    // are blocked by the side face. Only the band triangles near the receiver reveal that edge.
    std::vector<Triangle> tris = readAll(*makeBoxSource({{{-1, 0, -1}, {1, 1, 1}}}));
    ReceiverSet receivers;
    for (int i = 0; i < 40; ++i)
        for (float z : {-0.3f, 0.1f}) {
            receivers.position.push_back({1.0f - 0.00005f * float(i + 1), 1.0f - 6e-6f, z});
            receivers.normal.push_back({0, 1, 0});
        }
    const LightDesc light = rectLight({3, 1.007, 0}, {0, 0.01, 0}, {0, 0, 1}, 64, 2);
    requireSsvMatchesReference("grazing band", {light}, receivers, tris);
    LightSamples samples = generateLightSamples({light}, 64, 7);
    SsvStats stats;
    castSsv(samples, receivers, assignSets(receivers, samples.sets), tris, receiverEpsilonOf(CastOptions()), {}, &stats);
    CHECK(stats.bandEdges > 0);
}

TEST_CASE("ssv: a reference ray through a vertex is passed over, and with no candidate left the receiver is cast per sample",
          "[ssv][exact]") {
    const LightDesc light = rectLight({0.2, 4, 0.1}, {1, 0, 0}, {0, 0, 1}, 16, 1);
    const LightSamples samples = generateLightSamples({light}, 64, 7);
    // The first candidate is the sample nearest the light's centre; put a vertex of a blocker
    // exactly (halving is exact in float) on the receiver's segment to it.
    glm::dvec3 centre(0.0);
    for (const glm::dvec3& v : samples.lightBounds[0].vertices) centre += v / double(samples.lightBounds[0].vertices.size());
    int nearest = 0;
    for (int k = 1; k < samples.sampleCount; ++k)
        if (glm::length(glm::dvec3(samples.position(0, k)) - centre) < glm::length(glm::dvec3(samples.position(0, nearest)) - centre))
            nearest = k;
    const glm::vec3 m = 0.5f * samples.position(0, nearest);
    std::vector<Triangle> tris = {{{m, m + glm::vec3(0.5f, 0, 0.1f), m + glm::vec3(0.1f, 0, 0.6f)}, 0}};
    ReceiverSet receivers;
    receivers.position = {{0, 0, 0}, {0.05f, 0, 0.02f}};
    receivers.normal = {{0, 1, 0}, {0, 1, 0}};
    const std::vector<uint32_t> sets(receivers.size(), 0);
    const ReceiverEpsilon eps = receiverEpsilonOf(CastOptions());
    const VisibilityMasks reference = castReference(samples, receivers, sets, tris, eps);
    REQUIRE(reference.blockedCount() > 0);
    for (int candidates : {8, 1}) {
        SsvOptions options;
        options.referenceCandidates = candidates;
        SsvStats stats;
        const VisibilityMasks ssv = castSsv(samples, receivers, sets, tris, eps, options, &stats);
        INFO("candidates " << candidates);
        CHECK(ssv.words == reference.words);
        CHECK(stats.referenceRetries >= 1);
        CHECK(stats.fallbackFrustums == (candidates == 1 ? 1u : 0u));
    }
}
