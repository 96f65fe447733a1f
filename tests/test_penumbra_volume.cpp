// Conservativeness: every relation the blocking rule blocks lies inside V_L and inside V_Gk of
// the sample's group, for random triangles and every light type.

#include "TestScenes.h"

#include "bake/rule/BlockingRule.h"
#include "bake/cast/PenumbraVolume.h"

#include <catch2/catch.hpp>

using namespace penumbra;
using namespace penumbra::test;

namespace {

void checkConservative(const std::vector<LightDesc>& lights, uint64_t seed) {
    LightSamples samples = generateLightSamples(lights, 32, seed);
    std::vector<Triangle> tris = triangleSoup(seed, 40, {-2, 0.5f, -2}, {2, 3.5f, 2}, 1.5f);
    ReceiverSet receivers = randomReceivers(seed + 1, 400, {-4, -1, -4}, {4, 4, 4});
    uint64_t blocked = 0, outsideAll = 0;
    for (const Triangle& tri : tris) {
        BlockerTriangle t = BlockerTriangle::from(tri);
        REQUIRE(t.valid);
        std::vector<PenumbraVolume> lightVolumes, groupVolumes;
        for (const auto& b : samples.lightBounds) lightVolumes.push_back(makePenumbraVolume(b, t));
        for (const auto& g : samples.groups) groupVolumes.push_back(makePenumbraVolume(g.bound, t));
        for (size_t r = 0; r < receivers.size(); ++r) {
            glm::dvec3 p(receivers.position[r]);
            bool inAny = false;
            for (int set = 0; set < samples.sets; ++set)
                for (int k = 0; k < samples.groupCount(); ++k) {
                    const LightSampleGroup& g = samples.groups[k];
                    const PenumbraVolume& vl = lightVolumes[g.light];
                    const PenumbraVolume& vg = groupVolumes[k];
                    inAny = inAny || contains(vl, p, vl.all());
                    for (uint32_t j = 0; j < g.count; ++j) {
                        glm::dvec3 l(samples.position(set, int(g.first + j)));
                        if (!blocks(l, samples.w(g.light), p, t, ReceiverEpsilon{1e-5, 1.0})) continue;
                        ++blocked;
                        REQUIRE(contains(vl, p, vl.all()));
                        REQUIRE(contains(vg, p, vg.all()));
                    }
                }
            outsideAll += !inAny;
        }
    }
    INFO("blocked " << blocked << ", receivers outside V_L " << outsideAll);
    CHECK(blocked > 100);     // the test saw real shadows
    CHECK(outsideAll > 100);  // and the volumes really cull
}

}  // namespace

TEST_CASE("blocked relations lie inside V_L and V_Gk for every light type", "[hpc][volume]") {
    LightDesc rect = rectLight({0, 5, 0}, {2, 0.3, 0}, {0, 0.2, 1.5}, 128, 4);
    LightDesc disk;
    disk.type = LightType::Disk, disk.center = {0, 5, 0}, disk.normal = {0.3, -1, 0}, disk.radius = 1.0;
    disk.samples = 100, disk.sampleSets = 3;
    LightDesc sphere;
    sphere.type = LightType::Sphere, sphere.center = {0.3, 5, 0}, sphere.radius = 0.8, sphere.samples = 64;
    LightDesc polygon;
    polygon.type = LightType::Polygon, polygon.polygon = {{-1, 5, -1}, {1, 5, -1}, {0, 5, 1.5}};
    polygon.samples = 50;
    for (uint64_t seed : {1, 2}) {
        checkConservative({rect}, seed);
        checkConservative({disk}, seed);
        checkConservative({sphere}, seed);
        checkConservative({polygon}, seed);
    }
}

TEST_CASE("box classification against a penumbra volume prunes active planes", "[hpc][volume]") {
    LightSamples samples = generateLightSamples({rectLight({0, 4, 0}, {1, 0, 0}, {0, 0, 1}, 16, 1)}, 16, 1);
    Triangle tri{{glm::vec3(-0.5f, 2, -0.5f), glm::vec3(0.5f, 2, -0.5f), glm::vec3(0, 2, 0.5f)}, 0};
    PenumbraVolume v = makePenumbraVolume(samples.lightBounds[0], BlockerTriangle::from(tri));
    REQUIRE(v.count >= 4);  // cap plus separating planes
    uint32_t active = v.all();
    // Directly below the triangle, close to it: inside every plane, so every plane drops out.
    CHECK(intersects(v, Box{{-0.05f, 1.5f, -0.05f}, {0.05f, 1.6f, 0.05f}}, active));
    CHECK(active == 0);
    // Above the triangle (between it and the light): outside the cap.
    active = v.all();
    CHECK_FALSE(intersects(v, Box{{-0.1f, 2.5f, -0.1f}, {0.1f, 2.6f, 0.1f}}, active));
    // Far to the side on the floor: outside a separating plane.
    active = v.all();
    CHECK_FALSE(intersects(v, Box{{10, 0, 10}, {11, 0.1f, 11}}, active));
    // A box straddling the penumbra boundary keeps some planes active.
    active = v.all();
    CHECK(intersects(v, Box{{-3, 0, -3}, {0, 0.1f, 0}}, active));
    CHECK(active != 0);
}

TEST_CASE("box and point tests agree with evaluating every plane at the box corners", "[hpc][volume]") {
    LightSamples samples = generateLightSamples({rectLight({0, 5, 0}, {2, 0.3, 0}, {0, 0.2, 1.5}, 16, 1)}, 16, 3);
    Rng rng(11);
    uint64_t outside = 0, pruned = 0;
    for (const Triangle& tri : triangleSoup(5, 30, {-2, 0.5f, -2}, {2, 3.5f, 2}, 1.5f)) {
        PenumbraVolume v = makePenumbraVolume(samples.lightBounds[0], BlockerTriangle::from(tri));
        for (int i = 0; i < 200; ++i) {
            glm::vec3 a = randomIn(rng, {-5, -1, -5}, {5, 4, 5}), b = a + randomIn(rng, {0, 0, 0}, {1.5f, 1.5f, 1.5f});
            Box box{a, b};
            // Expected, plane by plane: outside if the farthest corner is behind, inside if the nearest is in front.
            bool expectOut = false;
            uint32_t expectActive = v.all();
            for (int k = 0; k < v.count; ++k) {
                double lo = INFINITY, hi = -INFINITY;
                for (int c = 0; c < 8; ++c) {
                    glm::dvec3 p(c & 1 ? b.x : a.x, c & 2 ? b.y : a.y, c & 4 ? b.z : a.z);
                    double e = v.plane(k).eval(p);
                    lo = std::min(lo, e), hi = std::max(hi, e);
                    CHECK(contains(v, p, 1u << k) == (e >= 0.0));
                }
                expectOut = expectOut || hi < 0.0;
                if (lo >= 0.0) expectActive &= ~(1u << k);
            }
            uint32_t active = v.all();
            const bool hit = intersects(v, box, active);
            REQUIRE(hit == !expectOut);
            if (hit) REQUIRE(active == expectActive);
            outside += !hit;
            pruned += hit && active != v.all();
        }
    }
    CHECK(outside > 100);
    CHECK(pruned > 100);
}
