// Conservativeness: every relation the blocking rule blocks lies inside V_L and inside V_Gk of
// the sample's group, for random triangles and every light type.

#include "TestScenes.h"

#include "bake/rule/BlockingRule.h"
#include "bake/cast/PenumbraVolume.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cstring>

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

namespace {

/// Whether two builds gave the same volume, bit for bit: the same planes in the same order (and
/// the zeroed slot after the last).
bool sameVolume(const PenumbraVolume& a, const PenumbraVolume& b) {
    if (a.count != b.count) return false;
    const size_t n = size_t(std::min(a.count + 1, PenumbraVolume::kMaxPlanes)) * sizeof(double);
    return std::memcmp(a.nx, b.nx, n) == 0 && std::memcmp(a.ny, b.ny, n) == 0 && std::memcmp(a.nz, b.nz, n) == 0 &&
           std::memcmp(a.d, b.d, n) == 0;
}

/// Blockers where candidates turn: random, level (plane misses the light), upright (plane cuts
/// it), tiny and far, large and near the light.
std::vector<Triangle> volumeBlockers(uint64_t seed) {
    std::vector<Triangle> out = triangleSoup(seed, 60, {-3, 0.2f, -3}, {3, 3.8f, 3}, 2.0f);
    for (size_t i = 0; i < out.size(); i += 5) out[i].v[1].y = out[i].v[2].y = out[i].v[0].y;  // level
    for (size_t i = 1; i < out.size(); i += 5) out[i].v[1].x = out[i].v[0].x, out[i].v[2].x = out[i].v[0].x;  // upright
    for (size_t i = 2; i < out.size(); i += 5)  // a blade: a few millimetres, far out
        for (glm::vec3& v : out[i].v) v = out[i].v[0] + (v - out[i].v[0]) * 0.002f + glm::vec3(40, 0, 0);
    for (size_t i = 3; i < out.size(); i += 5)
        for (glm::vec3& v : out[i].v) v = v * 3.0f + glm::vec3(0, 0.5f, 0);  // large, near the light
    return out;
}

}  // namespace

TEST_CASE("the AVX2 volume builder gives the scalar one's planes", "[hpc][volume][simd]") {
    if (!simdSupported(SimdLevel::Avx2)) {
        WARN("no AVX2 on this CPU: nothing to compare");
        return;
    }
    const std::vector<LightDesc> lights = {rectLight({0, 4, 0}, {4, 0, 0}, {0, 0, 4}), rectLight({0, 5, 0}, {2, 0.3, 0}, {0, 0.2, 1.5}),
                                           sunLight({0.3, -1, 0.2}, 5.0, 16), diskLight(), sphereLight(), polygonLight()};
    const Box receivers{{-4, -1, -4}, {4, 0.5f, 4}}, far{{30, -1, 30}, {31, 0, 31}};
    uint64_t builds = 0, planes = 0, culled = 0, maxBoundVertices = 0;
    for (const LightDesc& light : lights) {
        const LightSamples samples = generateLightSamples({light}, 64, 5);
        std::vector<const ConvexBound*> bounds = {&samples.lightBounds[0]};
        for (const LightSampleGroup& g : samples.groups) bounds.push_back(&g.bound);
        for (uint64_t seed : {1, 2, 3}) {
            for (const Triangle& tri : volumeBlockers(seed)) {
                const BlockerTriangle t = BlockerTriangle::from(tri);
                if (!t.valid) continue;
                for (const ConvexBound* bound : bounds) {
                    for (const Box* cull : {(const Box*)nullptr, &receivers, &far}) {
                        INFO("light " << int(light.type) << " seed " << seed << " cull " << (cull ? 1 : 0));
                        PenumbraVolume scalar, avx2;
                        const bool keptScalar = buildPenumbraVolume(*bound, t, scalar, cull, SimdLevel::Scalar);
                        const bool keptAvx2 = buildPenumbraVolume(*bound, t, avx2, cull, SimdLevel::Avx2);
                        REQUIRE(keptScalar == keptAvx2);
                        REQUIRE(sameVolume(scalar, avx2));
                        ++builds, planes += uint64_t(scalar.count), culled += !keptScalar;
                        maxBoundVertices = std::max<uint64_t>(maxBoundVertices, bound->vertices.size());
                    }
                }
            }
        }
    }
    INFO(builds << " builds, " << planes << " planes, " << culled << " culled, bounds up to " << maxBoundVertices << " vertices");
    CHECK(builds > 5000);
    CHECK(planes > 5 * builds);   // real volumes, not empty ones
    CHECK(culled > builds / 10);  // and the cull path was taken
    CHECK(maxBoundVertices > 4);  // lanes past four bound vertices
}

TEST_CASE("the AVX2 box test gives intersects()'s answer and active planes", "[hpc][volume][simd]") {
    if (!simdSupported(SimdLevel::Avx2)) {
        WARN("no AVX2 on this CPU: nothing to compare");
        return;
    }
    Rng rng(17);
    uint64_t tests = 0, outside = 0, pruned = 0, maxPlanes = 0;
    for (const LightDesc& light : {rectLight({0, 4, 0}, {4, 0, 0}, {0, 0, 4}), sunLight({0.3, -1, 0.2}, 5.0, 16), polygonLight()}) {
        const LightSamples samples = generateLightSamples({light}, 64, 5);
        for (const Triangle& tri : volumeBlockers(7)) {
            const BlockerTriangle t = BlockerTriangle::from(tri);
            if (!t.valid) continue;
            const PenumbraVolume v = makePenumbraVolume(samples.lightBounds[0], t);
            maxPlanes = std::max<uint64_t>(maxPlanes, uint64_t(v.count));
            for (int i = 0; i < 100; ++i) {
                const glm::vec3 a = randomIn(rng, {-5, -1, -5}, {5, 4, 5}), b = a + randomIn(rng, {0, 0, 0}, {2, 2, 2});
                // Every plane, then random subsets (a parent's pruned set), including planes in
                // the lanes of a block whose neighbours are inactive.
                const uint32_t subset = i == 0 ? v.all() : uint32_t(rng.next()) & v.all();
                uint32_t sse2 = subset, avx2 = subset;
                const bool hit = intersects(v, Box{a, b}, sse2);
                REQUIRE(intersectsAvx2(v, Box{a, b}, avx2) == hit);
                if (hit) REQUIRE(avx2 == sse2);
                ++tests, outside += !hit, pruned += hit && sse2 != subset;
            }
        }
    }
    INFO(tests << " tests, " << outside << " outside, " << pruned << " pruned, volumes up to " << maxPlanes << " planes");
    CHECK(outside > tests / 10);
    CHECK(pruned > tests / 10);
    CHECK(maxPlanes > 8);  // more than two blocks of four
}
