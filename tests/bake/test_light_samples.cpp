// Lights: stratified jittered samples, sample sets, spatial groups of <= 64, group bounds.

#include "TestScenes.h"

#include "bake/light/Light.h"
#include "stream/util/Error.h"

#include <catch2/catch.hpp>

#include <set>

using namespace penumbra;
using namespace penumbra::test;

namespace {

bool insidePolytope2D(const ConvexBound& b, const glm::dvec3& p, const glm::dvec3& n) {
    // For planar bounds: p projected on the plane lies inside the polygon of the first layer.
    size_t m = b.edges.size();
    for (const auto& e : b.edges) {
        glm::dvec3 a = b.vertices[e[0]], c = b.vertices[e[1]];
        if (glm::dot(glm::cross(c - a, p - a), n) < -1e-9) return false;
        if (--m == 0) break;
    }
    return true;
}

}  // namespace

TEST_CASE("rect samples are stratified: one per stratum in every set", "[lights]") {
    LightDesc l = rectLight({0, 5, 0}, {2, 0, 0}, {0, 0, 4}, 256, 8);
    LightSamples s = generateLightSamples({l}, 64, 3);
    REQUIRE(s.sampleCount == 256);
    REQUIRE(s.sets == 8);
    REQUIRE(s.groupCount() == 4);
    for (int set = 0; set < 8; ++set) {
        std::set<std::pair<int, int>> strata;
        for (int k = 0; k < 256; ++k) {
            glm::vec3 p = s.position(set, k);
            CHECK(p.y == 5.0f);
            double x = (p.x + 1.0) / 2.0 * 16, z = (p.z + 2.0) / 4.0 * 16;
            REQUIRE(x >= 0);
            REQUIRE(x < 16);
            strata.insert({int(x), int(z)});
        }
        CHECK(strata.size() == 256);
    }
    // Different sets jitter differently; the same seed gives the same samples.
    CHECK(s.position(0, 0) != s.position(1, 0));
    LightSamples again = generateLightSamples({l}, 64, 3);
    CHECK(again.positions == s.positions);
    CHECK(generateLightSamples({l}, 64, 4).positions != s.positions);
}

TEST_CASE("groups are spatially compact, at most 64 samples, and bound every set", "[lights]") {
    LightDesc disk;
    disk.type = LightType::Disk, disk.center = {1, 4, 0}, disk.normal = {0, -1, 0.3}, disk.radius = 0.7;
    disk.samples = 300, disk.sampleSets = 5;
    LightDesc rect = rectLight({0, 5, 0}, {1, 0.5, 0}, {0, 0.2, 1}, 200, 3);
    LightSamples s = generateLightSamples({rect, disk}, 64, 9);
    REQUIRE(s.sampleCount == 500);
    REQUIRE(s.sets == 5);
    uint32_t expectedFirst = 0;
    for (const LightSampleGroup& g : s.groups) {
        REQUIRE(g.count >= 1);
        REQUIRE(g.count <= 64);
        CHECK(g.first == expectedFirst);  // groups tile the sample range in order
        expectedFirst += g.count;
        glm::dvec3 n = g.light == 0 ? glm::normalize(glm::cross(rect.u, rect.v)) : glm::normalize(disk.normal);
        for (int set = 0; set < s.sets; ++set)
            for (uint32_t j = 0; j < g.count; ++j) CHECK(insidePolytope2D(g.bound, glm::dvec3(s.position(set, int(g.first + j))), n));
        // Compact: a group spans well under the whole light.
        glm::dvec3 lo(1e9), hi(-1e9);
        for (const auto& v : g.bound.vertices) lo = glm::min(lo, v), hi = glm::max(hi, v);
        CHECK(glm::length(hi - lo) < 1.3);
    }
    CHECK(expectedFirst == 500);
    CHECK(s.sampleLight[199] == 0);
    CHECK(s.sampleLight[200] == 1);
}

TEST_CASE("sphere samples lie in the ball and look like a uniform disk from every side", "[lights]") {
    LightDesc l;
    l.type = LightType::Sphere, l.center = {0, 3, 0}, l.radius = 2, l.samples = 512, l.sampleSets = 2;
    LightSamples s = generateLightSamples({l}, 64, 1);
    // Seen along any axis, the samples' offsets across it are uniform on the disk of the radius:
    // half of them lie within r / sqrt(2) of the centre (uniform in the ball, 37 % to 64 % did).
    for (glm::dvec3 axis : {glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1), glm::normalize(glm::dvec3(1, 2, -1))}) {
        int inner = 0;
        for (int k = 0; k < 512; ++k) {
            const glm::dvec3 d = glm::dvec3(s.position(0, k)) - l.center;
            REQUIRE(glm::length(d) <= 2.0 + 1e-5);
            inner += glm::length(d - glm::dot(d, axis) * axis) < 2.0 / std::sqrt(2.0);
        }
        INFO("axis " << axis.x << " " << axis.y << " " << axis.z);
        CHECK(inner > 226);
        CHECK(inner < 286);
    }
}

TEST_CASE("zero-area and invalid lights are rejected with the light named", "[lights]") {
    LightDesc l = rectLight({0, 5, 0}, {1, 0, 0}, {2, 0, 0});
    l.where = "scene.json: lights[0]";
    CHECK_THROWS_WITH(validateLight(l), Catch::Contains("scene.json: lights[0]") && Catch::Contains("zero-area"));
    LightDesc d;
    d.type = LightType::Disk, d.radius = 0, d.where = "L";
    CHECK_THROWS_WITH(validateLight(d), Catch::Contains("radius"));
    LightDesc p;
    p.type = LightType::Polygon, p.polygon = {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0.8, 0, 0.2}}, p.where = std::string("L");
    CHECK_THROWS_WITH(validateLight(p), Catch::Contains("not convex"));
    LightDesc nan = rectLight({0, NAN, 0}, {1, 0, 0}, {0, 0, 1});
    CHECK_THROWS_AS(validateLight(nan), InputError);
}

TEST_CASE("sample sets are assigned by a hash of the receiver index", "[lights]") {
    std::vector<int> histogram(8, 0);
    for (uint64_t i = 0; i < 8000; ++i) ++histogram[sampleSetOf(i, 8, 1)];
    for (int h : histogram) {
        CHECK(h > 850);
        CHECK(h < 1150);
    }
    CHECK(sampleSetOf(123, 8, 1) == sampleSetOf(123, 8, 1));
}
