// Tests for the Embree caster: it must agree with the brute-force reference (the blocking rule)
// on every relation except ties, and ties must be rare; plus exact analytic cases.

#include "TestScenes.h"

#include "bake/rule/BlockingRule.h"
#include "bake/peers/EmbreeCaster.h"
#include "bake/rule/TieClassifier.h"
#include "bake/light/Light.h"
#include "bake/peers/ReferenceCaster.h"
#include "stream/util/Random.h"

#include <catch2/catch.hpp>

#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <vector>

using namespace penumbra;
using penumbra::test::receiversFacingUp;

namespace {

/// Two triangles covering the axis-aligned rectangle [x0,x1] x [z0,z1] at height y.
void addQuadY(std::vector<Triangle>& out, float x0, float x1, float z0, float z1, float y) {
    Triangle a, b;
    a.v = {glm::vec3(x0, y, z0), glm::vec3(x1, y, z0), glm::vec3(x1, y, z1)};
    b.v = {glm::vec3(x0, y, z0), glm::vec3(x1, y, z1), glm::vec3(x0, y, z1)};
    out.push_back(a);
    out.push_back(b);
}

LightDesc rectLight(glm::dvec3 center, double size, int samples, int sets) {
    LightDesc l;
    l.type = LightType::Rect;
    l.center = center;
    l.u = {size, 0, 0};
    l.v = {0, 0, size};  // u x v points down: emits towards the scene below
    l.samples = samples;
    l.sampleSets = sets;
    return l;
}

std::vector<uint32_t> assignSets(size_t n, int sets, uint64_t seed) {
    std::vector<uint32_t> s(n);
    for (size_t i = 0; i < n; ++i) s[i] = uint32_t(sampleSetOf(i, sets, seed));
    return s;
}

struct Comparison {
    uint64_t relations = 0;
    uint64_t mismatches = 0;
    uint64_t embreeOnly = 0;    ///< blocked by Embree, lit by the rule
    uint64_t referenceOnly = 0; ///< blocked by the rule, lit by Embree
    uint64_t nonTies = 0;       ///< mismatches no triangle explains as a tie
    uint64_t blocked = 0;       ///< relations the reference blocks
};

/// Runs both casters and classifies every mismatch.
Comparison compare(const LightSamples& samples, const ReceiverSet& receivers, const std::vector<uint32_t>& sets,
                   const std::vector<Triangle>& triangles, double relativeEpsilon) {
    const ReceiverEpsilon epsilon{relativeEpsilon, 1.0};
    VisibilityMasks ref = castReference(samples, receivers, sets, triangles, epsilon);
    EmbreeStats stats;
    std::atomic<uint64_t> done{0};
    VisibilityMasks emb =
        castEmbree(samples, receivers, sets, triangles, epsilon, &stats, [&](uint64_t n) { done += n; });
    REQUIRE(emb.groups == ref.groups);
    REQUIRE(emb.words.size() == ref.words.size());
    CHECK(done.load() == receivers.size());
    CHECK(stats.rays <= uint64_t(receivers.size()) * uint64_t(samples.sampleCount));
    CHECK(stats.buildSeconds >= 0.0);
    CHECK(stats.traceSeconds >= 0.0);

    const TieClassifier classifier(triangles, epsilon);

    Comparison c;
    c.relations = uint64_t(receivers.size()) * uint64_t(samples.sampleCount);
    c.blocked = ref.blockedCount();
    for (size_t r = 0; r < receivers.size(); ++r) {
        const glm::dvec3 p(receivers.position[r]);
        for (int k = 0; k < ref.groups; ++k) {
            uint64_t diff = ref.row(r)[k] ^ emb.row(r)[k];
            const LightSampleGroup& g = samples.groups[k];
            for (uint32_t j = 0; j < g.count; ++j) {
                if (!(diff >> j & 1)) continue;
                ++c.mismatches;
                (ref.row(r)[k] >> j & 1 ? c.referenceOnly : c.embreeOnly)++;
                const glm::dvec3 l(samples.position(int(sets[r]), int(g.first + j)));
                const RelationVerdict v = classifier.classify(l, samples.w(g.light), p);
                if (!v.tie) {
                    ++c.nonTies;
                    UNSCOPED_INFO("non-tie mismatch: receiver " << r << " (" << p.x << ", " << p.y << ", " << p.z
                                                                << ") sample " << (g.first + j) << " ("
                                                                << l.x << ", " << l.y << ", " << l.z << "): " << v.describe());
                }
            }
            // Bits beyond the group's samples are never set.
            CHECK((emb.row(r)[k] & ~g.fullMask()) == 0);
        }
    }
    return c;
}

void requireAgreement(const Comparison& c) {
    INFO("relations " << c.relations << ", blocked by reference " << c.blocked << ", mismatches " << c.mismatches
                      << " (Embree only " << c.embreeOnly << ", reference only " << c.referenceOnly
                      << "), non-ties " << c.nonTies);
    CHECK(c.nonTies == 0);
    // The hit filter applies the rule to every candidate, so Embree never blocks what it does not.
    CHECK(c.embreeOnly == 0);
    CHECK(double(c.mismatches) < 1e-3 * double(c.relations));
}

}  // namespace

TEST_CASE("embree: ground grid under a blocker quad agrees with the reference", "[embree]") {
    std::vector<LightDesc> lights{rectLight({0, 3, 0}, 1.0, 256, 4)};
    const uint64_t seed = 17;
    LightSamples samples = generateLightSamples(lights, 64, seed);

    std::vector<Triangle> triangles;
    addQuadY(triangles, -3, 3, -3, 3, 0.0f);       // the ground the receivers lie on
    addQuadY(triangles, -0.5f, 0.5f, -0.5f, 0.5f, 1.0f);  // the blocker
    std::vector<glm::vec3> points;
    for (int i = 0; i <= 20; ++i)
        for (int j = 0; j <= 20; ++j) points.push_back(glm::vec3(-2.0f + 0.2f * i, 0.0f, -2.0f + 0.2f * j));
    ReceiverSet receivers = receiversFacingUp(points);
    auto sets = assignSets(receivers.size(), samples.sets, seed);

    for (double epsilon : {1e-5, 1e-3}) {
        Comparison c = compare(samples, receivers, sets, triangles, epsilon);
        INFO("epsilon " << epsilon);
        requireAgreement(c);
        CHECK(c.blocked > 0);
        CHECK(c.blocked < c.relations);
    }

    EmbreeStats stats;
    const VisibilityMasks filtered = castEmbree(samples, receivers, sets, triangles, ReceiverEpsilon{1e-5, 1.0}, &stats);
    CHECK(stats.rays == uint64_t(receivers.size()) * 256u);
    CHECK(stats.sceneBytes == 4u * 56u);  // 9 floats, 3 indices, the alpha id and longest edge per triangle
    CHECK(stats.filterCalls > 0);  // the blocker's hits
    CHECK(stats.filterExact <= stats.filterCalls);
    CHECK(stats.filterRejected <= stats.filterExact);  // only hits judged by the rule are rejected
    // Without the filter, Embree's native answer: the same shadows here, with no filter calls.
    EmbreeStats native;
    const VisibilityMasks unfiltered =
        castEmbree(samples, receivers, sets, triangles, ReceiverEpsilon{1e-5, 1.0}, &native, {}, false);
    CHECK(native.filterCalls == 0);
    CHECK(unfiltered.words == filtered.words);
}

TEST_CASE("embree: a narrow sun's near-parallel rays find a box's flat top from just under its edge", "[embree]") {
    // Receivers on a box's front face just under its top edge: their rays to a sun 0.001 degrees
    // wide enter the box and leave through its top, whose BVH box is flat. Embree's coherent-packet
    // frustum, for sixteen near-parallel rays, culled that box: 64 of 77,568 relations lit that the
    // rule blocks, 0.09 rad inside the top face (sweep X, stop 62). Each packet is now traced as
    // incoherent rays.
    const float h = 0.4f, top = 0.8f;
    const glm::vec3 c[8] = {{-h, 0, -h}, {h, 0, -h}, {h, top, -h}, {-h, top, -h}, {-h, 0, h}, {h, 0, h}, {h, top, h}, {-h, top, h}};
    const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {3, 7, 6, 2}, {0, 4, 7, 3}, {1, 2, 6, 5}};
    std::vector<Triangle> triangles;
    for (const auto& f : faces) {
        Triangle a, b;
        a.v = {c[f[0]], c[f[1]], c[f[2]]};
        b.v = {c[f[0]], c[f[2]], c[f[3]]};
        triangles.push_back(a), triangles.push_back(b);
    }
    addQuadY(triangles, -3, 3, -3, 3, 0.0f);
    for (double degrees : {1e-3, 1e-5}) {
        LightDesc sun;
        sun.type = LightType::Sun, sun.direction = {0.3, -1, 0.1}, sun.angularDiameterDeg = degrees, sun.samples = 16, sun.sampleSets = 8;
        const LightSamples samples = generateLightSamples({sun}, 64, 5);
        std::vector<glm::vec3> points;
        for (int i = 0; i < 24; ++i)
            for (int j = 1; j <= 8; ++j) points.push_back(glm::vec3(-0.38f + 0.033f * float(i), top - 0.004f * float(j), h));
        ReceiverSet receivers = receiversFacingUp(points);
        receivers.normal.assign(points.size(), glm::vec3(0, 0, 1));
        const auto sets = assignSets(receivers.size(), samples.sets, 5);
        INFO("sun " << degrees << " degrees");
        const Comparison cmp = compare(samples, receivers, sets, triangles, 1e-5);
        requireAgreement(cmp);
        CHECK(cmp.mismatches == 0);
        CHECK(cmp.blocked > cmp.relations / 2);  // most of these rays cross the box
    }
}

TEST_CASE("embree: analytic umbra and fully lit receivers", "[embree]") {
    std::vector<LightDesc> lights{rectLight({0, 3, 0}, 1.0, 128, 2)};
    const uint64_t seed = 5;
    for (int groupSize : {64, 37}) {
        LightSamples samples = generateLightSamples(lights, groupSize, seed);
        std::vector<Triangle> triangles;
        addQuadY(triangles, -5, 5, -5, 5, 1.0f);  // large blocker between light and ground
        // Directly below the centre (in umbra), far outside (fully lit), just below the light's
        // centre but above the blocker (fully lit).
        ReceiverSet receivers =
            receiversFacingUp({glm::vec3(0, 0, 0), glm::vec3(0.3f, -2, -0.2f), glm::vec3(100, 0, 0), glm::vec3(0, 2, 0)});
        auto sets = assignSets(receivers.size(), samples.sets, seed);
        VisibilityMasks emb = castEmbree(samples, receivers, sets, triangles, ReceiverEpsilon{1e-5, 1.0});
        VisibilityMasks ref = castReference(samples, receivers, sets, triangles, ReceiverEpsilon{1e-5, 1.0});
        INFO("group size " << groupSize);
        for (int k = 0; k < samples.groupCount(); ++k) {
            CHECK(emb.row(0)[k] == samples.groups[k].fullMask());
            CHECK(emb.row(1)[k] == samples.groups[k].fullMask());
            CHECK(emb.row(2)[k] == 0);
            CHECK(emb.row(3)[k] == 0);
        }
        CHECK(emb.words == ref.words);
        CHECK(emb.visibleFraction(0, samples) == 0.0);
        CHECK(emb.visibleFraction(2, samples) == 1.0);
    }
}

TEST_CASE("embree: random triangle soups agree with the reference up to ties", "[embree]") {
    for (uint64_t seed : {1u, 2u, 3u}) {
        Rng rng(hashIndex(0xe3b, seed));
        // Lights: 64..256 samples in 2..4 sets, group sizes that do and do not divide 16.
        std::vector<LightDesc> lights;
        lights.push_back(rectLight({rng.uniform(-1, 1), 4.5, rng.uniform(-1, 1)}, 1.5, 64, 2 + int(seed % 3)));
        if (seed != 1) {
            LightDesc disk;
            disk.type = LightType::Disk;
            disk.center = {rng.uniform(-2, 2), 4.0, rng.uniform(-2, 2)};
            disk.normal = glm::normalize(glm::dvec3(0.3, -1, 0.2));
            disk.radius = 0.6;
            disk.samples = seed == 2 ? 64 : 192;
            disk.sampleSets = 3;
            lights.push_back(disk);
        }
        const int groupSize = seed == 3 ? 23 : 64;
        LightSamples samples = generateLightSamples(lights, groupSize, seed);
        REQUIRE(samples.sampleCount >= 64);
        REQUIRE(samples.sampleCount <= 256);

        std::vector<Triangle> triangles;
        addQuadY(triangles, -4, 4, -4, 4, 0.0f);
        for (int i = 0; i < 150; ++i) {  // a soup of random triangles
            glm::dvec3 c(rng.uniform(-2, 2), rng.uniform(0.5, 2.5), rng.uniform(-2, 2));
            Triangle t;
            for (auto& v : t.v)
                v = glm::vec3(c + glm::dvec3(rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4)));
            triangles.push_back(t);
        }
        // A tilted mesh with shared edges and vertices (edge ties).
        {
            glm::dvec3 o(rng.uniform(-1, 1), 1.5, rng.uniform(-1, 1));
            glm::dvec3 a(0.25, 0.05, 0.0), b(0.0, -0.08, 0.25);
            auto at = [&](int i, int j) { return glm::vec3(o + double(i) * a + double(j) * b); };
            for (int i = 0; i < 6; ++i)
                for (int j = 0; j < 6; ++j) {
                    Triangle t1, t2;
                    t1.v = {at(i, j), at(i + 1, j), at(i + 1, j + 1)};
                    t2.v = {at(i, j), at(i + 1, j + 1), at(i, j + 1)};
                    triangles.push_back(t1);
                    triangles.push_back(t2);
                }
        }
        // Triangles that block nothing: zero area and non-finite.
        {
            Triangle degenerate;
            degenerate.v = {glm::vec3(0, 1, 0), glm::vec3(1, 1, 0), glm::vec3(2, 1, 0)};
            Triangle nan;
            nan.v = {glm::vec3(0, 1, 0), glm::vec3(std::numeric_limits<float>::quiet_NaN(), 1, 0), glm::vec3(0, 1, 1)};
            triangles.push_back(degenerate);
            triangles.push_back(nan);
        }

        // Receivers: on the ground, in free space, and on the soup's triangles (self-shadowing).
        std::vector<glm::vec3> points;
        for (int i = 0; i < 120; ++i) points.push_back(glm::vec3(float(rng.uniform(-3, 3)), 0.0f, float(rng.uniform(-3, 3))));
        for (int i = 0; i < 100; ++i)
            points.push_back(glm::vec3(rng.uniform(-2.5, 2.5), rng.uniform(0.0, 3.0), rng.uniform(-2.5, 2.5)));
        for (int i = 0; i < 100; ++i) {
            const Triangle& t = triangles[2 + size_t(rng.uniform(0, 150))];
            double u = rng.uniform(), v = rng.uniform();
            if (u + v > 1) u = 1 - u, v = 1 - v;
            glm::dvec3 q = glm::dvec3(t.v[0]) + u * glm::dvec3(t.v[1] - t.v[0]) + v * glm::dvec3(t.v[2] - t.v[0]);
            points.push_back(glm::vec3(q));
        }
        ReceiverSet receivers = receiversFacingUp(points);
        auto sets = assignSets(receivers.size(), samples.sets, seed);

        Comparison c = compare(samples, receivers, sets, triangles, 1e-5);
        INFO("seed " << seed << ", " << samples.sampleCount << " samples in " << samples.sets << " sets, "
                     << samples.groupCount() << " groups");
        requireAgreement(c);
        CHECK(c.blocked > c.relations / 20);  // the scene does cast shadows
    }
}

TEST_CASE("embree: a receiver or sample beyond Embree's ray range is a one-line error, not an assertion", "[embree]") {
    // Embree asserts that ray origins and directions stay within 1.8e18 (an abort, exit 134);
    // the other methods bake these relations, so Embree refuses them up front. (Lights cannot be
    // that far: the scene refuses coordinates beyond 1e15.)
    std::vector<LightDesc> lights{rectLight({0, 3, 0}, 1.0, 16, 1)};
    LightSamples samples = generateLightSamples(lights, 16, 9);
    for (float far : {1e19f, -1e20f}) {
        ReceiverSet receivers = receiversFacingUp({glm::vec3(0, 0, 0), glm::vec3(0, far, 0)});
        auto sets = assignSets(receivers.size(), samples.sets, 9);
        CHECK_THROWS_WITH(castEmbree(samples, receivers, sets, {}, ReceiverEpsilon{1e-5, 1.0}),
                          Catch::Contains("--method embree: receiver 1") && Catch::Contains("beyond the range of Embree's rays"));
    }
}

TEST_CASE("embree: no triangles gives all-zero masks", "[embree]") {
    std::vector<LightDesc> lights{rectLight({0, 3, 0}, 1.0, 64, 2)};
    LightSamples samples = generateLightSamples(lights, 64, 9);
    ReceiverSet receivers = receiversFacingUp({glm::vec3(0, 0, 0), glm::vec3(1, 0, 1), glm::vec3(-1, 2, 0)});
    auto sets = assignSets(receivers.size(), samples.sets, 9);

    EmbreeStats stats;
    VisibilityMasks masks = castEmbree(samples, receivers, sets, {}, ReceiverEpsilon{1e-5, 1.0}, &stats);
    REQUIRE(masks.receivers() == receivers.size());
    REQUIRE(masks.groups == samples.groupCount());
    CHECK(masks.blockedCount() == 0);
    CHECK(stats.sceneBytes == 0);
    CHECK(stats.rays == receivers.size() * 64u);

    // Only invalid triangles: the same.
    Triangle degenerate, inf;
    degenerate.v = {glm::vec3(0, 1, 0), glm::vec3(0, 1, 0), glm::vec3(1, 1, 1)};
    inf.v = {glm::vec3(-1, 1, -1), glm::vec3(std::numeric_limits<float>::infinity(), 1, 0), glm::vec3(1, 1, 1)};
    std::vector<Triangle> invalid{degenerate, inf};
    masks = castEmbree(samples, receivers, sets, invalid, ReceiverEpsilon{1e-5, 1.0}, &stats);
    CHECK(masks.blockedCount() == 0);
    CHECK(stats.sceneBytes == 0);

    // No receivers at all.
    ReceiverSet none;
    masks = castEmbree(samples, none, {}, invalid, ReceiverEpsilon{1e-5, 1.0});
    CHECK(masks.words.empty());
}

// Two relations of grids at 1280x960 with the 4x light (bench table2), where the peer once
// differed from the rule by more than a tie. Both blockers are bar faces: slivers 4.9 long and
// 0.04 wide, seen from a receiver a few millimetres away near their short edge, where Embree's
// float barycentrics are off by more than a fixed 1e-5. One ray passes 3e-3 rad inside the sliver
// (the rule blocks; Embree's test reported no hit until the triangle was anchored at its short
// edge), the other 4.8e-6 outside in barycentrics (the rule does not block; the fixed margin of
// the filter's shortcut accepted Embree's hit, 1.6e-5 inside).
TEST_CASE("embree: a long sliver near its short edge is neither missed nor blocked falsely", "[embree]") {
    struct Case {
        const char* what;
        std::array<glm::vec3, 3> sliver;
        glm::vec3 receiver, sample;
        bool ruleBlocks;
    };
    const Case cases[] = {
        {"missed hit",
         {glm::vec3(-2.62792778f, 2.22000003f, -0.493750215f), glm::vec3(1.71883678f, 2.22000003f, 2.06834197f),
          glm::vec3(1.74156404f, 2.22000003f, 2.02897716f)},
         glm::vec3(1.72909248f, 2.21483135f, 2.05057859f), glm::vec3(1.75992799f, 6.0f, 1.97444415f), true},
        {"false block",
         {glm::vec3(-2.93474579f, 2.18000007f, 0.037674468f), glm::vec3(1.43474591f, 2.18000007f, 2.56040168f),
          glm::vec3(1.43474591f, 2.22000003f, 2.56040168f)},
         glm::vec3(1.4342345f, 2.20582986f, 2.5612874f), glm::vec3(1.81549609f, 6.0f, 1.93559027f), false},
    };
    const ReceiverEpsilon epsilon{1e-5, 6.999936103820801};
    for (const Case& c : cases) {
        INFO(c.what);
        LightSamples samples = generateLightSamples({rectLight({0, 6, 0}, 4.0, 1, 1)}, 64, 1);
        samples.positions[0] = c.sample;  // the relation's own sample
        const ReceiverSet receivers = receiversFacingUp({c.receiver});
        const std::vector<uint32_t> sets{0};
        // Every rotation of the vertices: the peer must not depend on which vertex comes first.
        for (int first = 0; first < 3; ++first) {
            Triangle t;
            for (int k = 0; k < 3; ++k) t.v[size_t(k)] = c.sliver[size_t((first + k) % 3)];
            const std::vector<Triangle> triangles{t};
            INFO("first vertex " << first);
            REQUIRE(blocks(glm::dvec3(c.sample), 1.0, glm::dvec3(c.receiver), BlockerTriangle::from(t), epsilon) ==
                    c.ruleBlocks);
            const VisibilityMasks emb = castEmbree(samples, receivers, sets, triangles, epsilon);
            CHECK(bool(emb.row(0)[0] & 1) == c.ruleBlocks);
        }
    }
}
