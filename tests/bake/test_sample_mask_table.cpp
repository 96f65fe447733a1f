// The sample mask table (Sintorn et al. 2008, Section 4.2, made exact): every bit it decides is
// the blocking rule's own decision, and hierarchical penumbra casting with the table on stays
// bit-identical to the reference.

#include "TestScenes.h"

#include "bake/rule/BlockingRule.h"
#include "bake/cast/SampleMaskTable.h"

#include <catch2/catch.hpp>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// How often each kind of bit occurred, so a test can show it would notice a wrong table.
struct Tally {
    uint64_t sure = 0;             // decided blocked by the table
    uint64_t excluded = 0;         // decided not blocked (outside maybe)
    uint64_t undecided = 0;        // left to the exact test
    uint64_t blockedNotSure = 0;   // would be wrong if maybe were replaced by sure
    uint64_t maybeNotBlocked = 0;  // would be wrong if sure were replaced by maybe
};

/// Checks, for receiver @p r against triangle @p t, every sample of every set: per edge, the
/// exact edge-plane decision lies between that edge's sure and maybe rows; per relation, the
/// rule's decision lies between the AND of the sure rows and the AND of the maybe rows.
void checkReceiver(const LightSamples& samples, const SampleMaskTable& table, const BlockerTriangle& t,
                   const glm::dvec3& r, Tally& tally) {
    const ReceiverEpsilon epsilon = receiverEpsilonOf(CastOptions());
    const SampleMaskTable::Blocker blocker = table.prepare(t);
    const double dist = distanceBehind(t, r), eps = epsilon.at(r);
    const double w = samples.w(samples.groups[table.firstGroup()].light);
    for (uint32_t set = 0; set < uint32_t(samples.sets); ++set) {
        SampleMaskTable::Rows rows;
        const SampleMaskTable::Lookup lookup = table.lookup(blocker, set, r, dist, eps, rows);
        if (lookup == SampleMaskTable::Lookup::Exact) continue;
        for (uint32_t k = 0; k < uint32_t(samples.groupCount()); ++k) {
            const LightSampleGroup& group = samples.groups[k];
            const uint32_t local = k - table.firstGroup();
            for (uint32_t j = 0; j < group.count; ++j) {
                const glm::dvec3 l(samples.position(int(set), int(group.first + j)));
                const bool blocked = blocks(l, w, r, t, epsilon);
                const uint64_t bit = 1ull << j;
                if (lookup == SampleMaskTable::Lookup::NoneBlocked) {
                    if (blocked) FAIL("a blocked relation in a receiver the table said nothing blocks");
                    ++tally.excluded;
                    continue;
                }
                const HardShadowVolume h = makeHardShadowVolume(l, w, t);
                // For a split blocker the edge rows hold the orientation of the samples beyond T
                // from r; the others cannot be blocked and their edge rows mean nothing.
                const bool edgeRowsApply = !blocker.split || h.side * dist > 0.0;
                // (FAIL only on a violation: a REQUIRE per bit would dominate the test's time.)
                for (int e = 0; e < 3 && edgeRowsApply; ++e) {
                    const bool inside = edgeValue(h, t, e, r) >= 0.0;
                    INFO("set " << set << " group " << k << " sample " << j << " edge " << e);
                    if ((rows.sureWord(e, local) & bit) && !inside) FAIL("sure, but outside the edge plane");
                    if (!(rows.maybeWord(e, local) & bit) && inside) FAIL("not maybe, but inside the edge plane");
                }
                const bool sure = rows.sureWord(local) & bit, maybe = rows.maybeWord(local) & bit;
                if (sure && !blocked) FAIL("sure, but not blocked");
                if (!maybe && blocked) FAIL("not maybe, but blocked");
                tally.sure += sure;
                tally.excluded += !maybe;
                tally.undecided += maybe && !sure;
                tally.blockedNotSure += blocked && !sure;
                tally.maybeNotBlocked += maybe && !blocked;
            }
        }
    }
}

/// Random blockers between a light and a floor, random receivers, and receivers placed so that an
/// edge's line passes (up to float rounding) through a light sample: the hardest cells.
void checkLight(const LightDesc& light, int angles, int offsets) {
    LightSamples samples = generateLightSamples({light}, 64, 3);
    SampleMaskTable table(samples, 0, angles, offsets);
    REQUIRE(table.usable());
    std::vector<Triangle> tris = triangleSoup(11, 40, {-2, 1, -2}, {2, 3, 2}, 1.5f);
    Rng rng(12);
    Tally tally;
    for (const Triangle& tri : tris) {
        const BlockerTriangle t = BlockerTriangle::from(tri);
        if (!t.valid) continue;
        for (int i = 0; i < 20; ++i) {
            glm::dvec3 r(glm::vec3(randomIn(rng, {-3, -0.5f, -3}, {3, 1, 3})));
            checkReceiver(samples, table, t, r, tally);
        }
        for (int i = 0; i < 6; ++i) {  // r on the line from a sample through a point of an edge
            const glm::dvec3 l(samples.position(int(rng.next() % uint64_t(samples.sets)), int(rng.next() % uint64_t(samples.sampleCount))));
            const int e = int(rng.next() % 3);
            const double s = i < 2 ? 0.0 : rng.uniform();  // through a vertex, or along the edge
            const glm::dvec3 onEdge = t.v[e] + s * (t.v[(e + 1) % 3] - t.v[e]);
            // Away from the sample through the edge point: for a sun, against its direction.
            const glm::dvec3 away = samples.w(0) == 0.0 ? -glm::normalize(l) : onEdge - l;
            const glm::dvec3 r(glm::vec3(onEdge + (0.5 + rng.uniform()) * away));
            checkReceiver(samples, table, t, r, tally);
        }
    }
    INFO("sure " << tally.sure << ", excluded " << tally.excluded << ", undecided " << tally.undecided);
    CHECK(tally.sure > 0);
    CHECK(tally.excluded > 0);
    CHECK(tally.undecided > 0);
    // Both corruptions would be caught: some blocked samples are not sure (so "maybe" as "sure"
    // fails) and some maybe samples are not blocked (so "sure" as "maybe" fails).
    CHECK(tally.blockedNotSure > 0);
    CHECK(tally.maybeNotBlocked > 0);
    // The point of the table: most relations are decided without the exact test.
    CHECK(tally.undecided * 4 < tally.sure + tally.excluded);
}

}  // namespace

TEST_CASE("sample mask table cells bracket the exact decisions", "[table]") {
    SECTION("rect, 128 x 128") { checkLight(rectLight({0, 4, 0}, {1.3, 0.2, 0}, {0, 0.1, 1.1}, 64, 4), 128, 128); }
    SECTION("rect, coarse 16 x 8") { checkLight(rectLight({0, 4, 0}, {1.3, 0.2, 0}, {0, 0.1, 1.1}, 64, 4), 16, 8); }
    SECTION("disk") { checkLight(diskLight(), 64, 256); }
    SECTION("polygon") { checkLight(polygonLight(), 256, 64); }
    SECTION("sun") {  // the table lives in the plane of the sun's directions
        LightDesc sun;
        sun.type = LightType::Sun, sun.direction = {0.3, -1, 0.2}, sun.angularDiameterDeg = 8;
        sun.samples = 64, sun.sampleSets = 4;
        checkLight(sun, 128, 128);
    }
}

TEST_CASE("sample mask table refuses volumetric lights", "[table]") {
    LightSamples samples = generateLightSamples({sphereLight()}, 64, 3);
    SampleMaskTable table(samples, 0);
    CHECK_FALSE(table.usable());
    CHECK(table.bytes() == 0);
    BlockerTriangle t = BlockerTriangle::from({{glm::vec3(0, 2, 0), glm::vec3(1, 2, 0), glm::vec3(0, 2, 1)}, 0});
    SampleMaskTable::Rows rows;
    CHECK(table.lookup(table.prepare(t), 0, {0.2, 0, 0.2}, -2.0, 1e-5, rows) == SampleMaskTable::Lookup::Exact);
}

TEST_CASE("sample mask table splits a light that a blocker's plane cuts", "[table]") {
    LightSamples samples = generateLightSamples({rectLight({0, 4, 0}, {2, 0, 0}, {0, 0, 2}, 64, 2)}, 64, 3);
    SampleMaskTable table(samples, 0);
    REQUIRE(table.usable());
    BlockerTriangle through = BlockerTriangle::from({{glm::vec3(0, 2, 0), glm::vec3(0, 5, 0), glm::vec3(0, 2, 1)}, 0});
    CHECK(table.prepare(through).usable);
    CHECK(table.prepare(through).split);
    BlockerTriangle below = BlockerTriangle::from({{glm::vec3(0, 2, 0), glm::vec3(1, 2, 0), glm::vec3(0, 2, 1)}, 0});
    CHECK(table.prepare(below).usable);
    CHECK_FALSE(table.prepare(below).split);
    // Split blockers: vertical blades and walls under a light twice as wide, decided by the rows
    // exactly as the rule decides them.
    Tally tally;
    Rng rng(21);
    for (int i = 0; i < 60; ++i) {
        const glm::vec3 base = randomIn(rng, {-1.5f, 0, -1.5f}, {1.5f, 0, 1.5f});
        const glm::vec3 side = randomIn(rng, {-0.3f, 0, -0.3f}, {0.3f, 0, 0.3f});
        const BlockerTriangle t = BlockerTriangle::from({{base, base + side, base + glm::vec3(0.1f, 5.0f, 0.05f)}, 0});
        if (!t.valid || !table.prepare(t).split) continue;
        for (int j = 0; j < 40; ++j) checkReceiver(samples, table, t, glm::dvec3(glm::vec3(randomIn(rng, {-3, -0.5f, -3}, {3, 1, 3}))), tally);
    }
    INFO("sure " << tally.sure << ", excluded " << tally.excluded << ", undecided " << tally.undecided);
    CHECK(tally.sure > 0);
    CHECK(tally.undecided * 4 < tally.sure + tally.excluded);
}

TEST_CASE("the AVX2 edge look-up finds the rows of the scalar one, receiver by receiver", "[table][simd]") {
    if (!simdSupported(SimdLevel::Avx2)) {
        WARN("no AVX2 on this CPU: only the scalar look-up runs");
        return;
    }
    LightDesc sun;
    sun.type = LightType::Sun, sun.direction = {0.3, -1, 0.2}, sun.angularDiameterDeg = 8, sun.samples = 64, sun.sampleSets = 4;
    const std::vector<LightDesc> lights = {rectLight({0, 4, 0}, {1.3, 0.2, 0}, {0, 0.1, 1.1}, 64, 4), diskLight(), polygonLight(),
                                           sun, rectLight({0, 4, 0}, {2, 0, 0}, {0, 0, 2}, 64, 2)};
    Rng rng(33);
    uint64_t rowsFound = 0, exact = 0, none = 0;
    for (const LightDesc& light : lights) {
        const LightSamples samples = generateLightSamples({light}, 64, 3);
        const SampleMaskTable avx2(samples, 0, 64, 64, SimdLevel::Avx2), scalar(samples, 0, 64, 64, SimdLevel::Scalar);
        std::vector<Triangle> tris = triangleSoup(17, 40, {-2, 1, -2}, {2, 3, 2}, 1.5f);
        for (int i = 0; i < 20; ++i) {  // upright blades: planes that cut the light (split blockers)
            const glm::vec3 base = randomIn(rng, {-1.5f, 0, -1.5f}, {1.5f, 0, 1.5f});
            tris.push_back({{base, base + randomIn(rng, {-0.3f, 0, -0.3f}, {0.3f, 0, 0.3f}), base + glm::vec3(0.1f, 5.0f, 0.05f)}, 0});
        }
        // An upright triangle with a level top edge: a receiver level with that edge lies in a plane
        // through it parallel to the light, a line the table cannot place (Lookup::Exact).
        tris.push_back({{glm::vec3(-1, 2, 0), glm::vec3(1, 2, 0), glm::vec3(0, 0.5f, 0)}, 0});
        const ReceiverEpsilon epsilon = receiverEpsilonOf(CastOptions());
        for (const Triangle& tri : tris) {
            const BlockerTriangle t = BlockerTriangle::from(tri);
            if (!t.valid) continue;
            const SampleMaskTable::Blocker b = avx2.prepare(t);
            for (int i = 0; i < 30; ++i) {
                // Random receivers, and some on T's plane and edges (zero distance, zero-length lines).
                glm::dvec3 r(glm::vec3(randomIn(rng, {-3, -0.5f, -3}, {3, 1, 3})));
                if (i % 10 == 0) r = t.v[i / 10 % 3];
                if (i % 10 == 1) r = 0.5 * (t.v[0] + t.v[1]);
                if (i % 10 == 2) r = {0.3 - 0.1 * (i / 10), 2.0, i < 15 ? 1.5 : -1.5};
                const double dist = distanceBehind(t, r), eps = epsilon.at(r);
                for (uint32_t set = 0; set < uint32_t(samples.sets); ++set) {
                    SampleMaskTable::Rows a, s;
                    const SampleMaskTable::Lookup la = avx2.lookup(b, set, r, dist, eps, a), ls = scalar.lookup(b, set, r, dist, eps, s);
                    REQUIRE(la == ls);
                    rowsFound += la == SampleMaskTable::Lookup::Rows, exact += la == SampleMaskTable::Lookup::Exact;
                    none += la == SampleMaskTable::Lookup::NoneBlocked;
                    if (la != SampleMaskTable::Lookup::Rows) continue;
                    for (uint32_t k = 0; k < uint32_t(samples.groupCount()); ++k)
                        for (int e = 0; e < 4; ++e) {
                            INFO("set " << set << " group " << k << " line " << e);
                            REQUIRE(a.sureWord(e, k) == s.sureWord(e, k));
                            REQUIRE(a.maybeWord(e, k) == s.maybeWord(e, k));
                        }
                }
            }
        }
    }
    INFO("rows " << rowsFound << ", exact " << exact << ", none blocked " << none);
    CHECK(rowsFound > 1000);
    CHECK(exact > 0);
    CHECK(none > 0);
}

TEST_CASE("penumbra casting with the sample mask table matches the reference", "[hpc][table][exact]") {
    std::vector<Triangle> tris;
    ReceiverSet receivers;
    soupOverFloor(tris, receivers);

    const LightDesc rect = rectLight({0, 4, 0}, {1.3, 0.2, 0}, {0, 0.1, 1.1}, 64, 4);
    const std::vector<std::pair<std::string, std::vector<LightDesc>>> scenes = {
        {"rect", {rect}},
        {"disk", {diskLight()}},
        {"polygon", {polygonLight()}},
        {"sphere (fallback)", {sphereLight()}},
        {"all four", {rect, diskLight(), sphereLight(), polygonLight()}},
    };
    for (const auto& [scene, lights] : scenes) {
        LightSamples samples = generateLightSamples(lights, 32, 7);
        std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
        VisibilityMasks reference = castReference(samples, receivers, sets, tris, receiverEpsilonOf(CastOptions()));
        INFO(scene << ": " << reference.blockedCount() << " blocked");
        REQUIRE(reference.blockedCount() > 0);
        for (auto [name, options] : optionVariants()) {
            options.sampleTable = true;
            for (int tiles : {1, 3}) {
                INFO(name << ", tiles " << tiles);
                CastStats stats;
                VisibilityMasks hpc = castHpc(samples, receivers, sets, tris, options, tiles, 97, &stats);
                CHECK(hpc.words == reference.words);
                // The table must really have decided relations, or this test proves nothing.
                if (scene.starts_with("sphere")) CHECK(stats.tableDecidedRelations == 0);
                else CHECK(stats.tableDecidedRelations > 0);
            }
        }
    }
}
