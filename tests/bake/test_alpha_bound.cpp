// A group's alpha test at once (bake/rule/AlphaBound.h): AlphaTable::verdictOver() on regions of
// known outlines and texels, every Opaque or Clear verdict of alphaOverBound() checked against
// every hit's own alpha test (every light kind, outlines, textures, max_distance ids), and hpc
// with the bounds on giving the reference's bits while the bounds decide groups; the four-lane
// outline test (bake/cast/OutlineTest.h) against the scalar alpha test, lane by lane.

#include "AlphaScenes.h"
#include "TestScenes.h"

#include "bake/cast/HardShadowBlock.h"
#include "bake/cast/OutlineTest.h"
#include "bake/cast/SimdLevel.h"
#include "bake/rule/AlphaBound.h"
#include "bake/rule/AlphaRule.h"
#include "stream/AlphaTable.h"

#include <catch2/catch.hpp>

#include <array>
#include <vector>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// Barycentrics of the corners of the (u, v) box [u0, u1] x [v0, v1] on the canonical lower
/// triangle (0,0) (1,0) (1,1): u = b1 + b2, v = b2.
std::vector<std::array<double, 3>> lowerBox(double u0, double u1, double v0, double v1) {
    std::vector<std::array<double, 3>> corners;
    for (double u : {u0, u1})
        for (double v : {v0, v1}) corners.push_back({1.0 - u, u - v, v});
    return corners;
}

struct VerdictCounts {
    uint64_t opaque = 0, clear = 0, mixed = 0, hitsChecked = 0;
};

/// Every (receiver, alpha triangle, group): the verdict, and for a decided one each hit's test.
VerdictCounts checkVerdicts(const std::vector<Triangle>& scene, const AlphaTable& table, const LightSamples& samples,
                            const ReceiverSet& receivers) {
    VerdictCounts n;
    const ReceiverEpsilon eps = receiverEpsilonOf(CastOptions());
    for (const Triangle& raw : scene) {
        const BlockerTriangle t = BlockerTriangle::from(raw);
        if (!t.valid || t.alpha == 0) continue;
        for (size_t r = 0; r < receivers.size(); ++r) {
            const glm::dvec3 p(receivers.position[r]);
            const double dist = distanceBehind(t, p);
            for (const LightSampleGroup& g : samples.groups) {
                const AlphaVerdict verdict = alphaOverBound(table, t, p, g.bound);
                if (verdict == AlphaVerdict::Mixed) {
                    ++n.mixed;
                    continue;
                }
                ++(verdict == AlphaVerdict::Opaque ? n.opaque : n.clear);
                const double w = samples.w(g.light);
                for (int set = 0; set < samples.sets; ++set)
                    for (uint32_t j = 0; j < g.count; ++j) {
                        const HardShadowVolume h = makeHardShadowVolume(glm::dvec3(samples.position(set, int(g.first + j))), w, t);
                        if (!blocks(h, t, p, dist, eps.at(p))) continue;
                        ++n.hitsChecked;
                        INFO("receiver " << r << ", group " << (&g - samples.groups.data()) << ", sample " << j);
                        REQUIRE(alphaAtHit(table, h, t, p).opaque == (verdict == AlphaVerdict::Opaque));
                    }
            }
        }
    }
    return n;
}

}  // namespace

TEST_CASE("alpha bound: verdictOver decides regions inside and outside outlines and texels, and only those",
          "[alpha]") {
    const AlphaTable table;
    // Leaf |2v - 1| < 4u(1 - u): opaque around (0.5, 0.5), clear near the corner (0, 1).
    CHECK(table.verdictOver(kAlphaLeafLower, lowerBox(0.45, 0.55, 0.45, 0.5), 0.0) == AlphaVerdict::Opaque);
    CHECK(table.verdictOver(kAlphaLeafLower, lowerBox(0.9, 0.95, 0.9, 0.92), 0.0) == AlphaVerdict::Clear);
    CHECK(table.verdictOver(kAlphaLeafLower, lowerBox(0.45, 0.55, 0.0, 0.5), 0.0) == AlphaVerdict::Mixed);
    // A pad that reaches over the outline makes it Mixed.
    CHECK(table.verdictOver(kAlphaLeafLower, lowerBox(0.5, 0.5, 0.5, 0.5), 0.4) == AlphaVerdict::Mixed);
    // Petal: the disc (2u - 1)^2 + (2v - 1)^2 < 1.
    CHECK(table.verdictOver(kAlphaPetalLower, lowerBox(0.6, 0.7, 0.3, 0.4), 0.0) == AlphaVerdict::Opaque);
    CHECK(table.verdictOver(kAlphaPetalLower, lowerBox(0.97, 0.99, 0.9, 0.95), 0.0) == AlphaVerdict::Clear);
    CHECK(table.verdictOver(kAlphaPetalLower, lowerBox(0.5, 1.0, 0.4, 0.5), 0.0) == AlphaVerdict::Mixed);
    // An id the table does not hold is opaque, as lookup() says.
    CHECK(table.verdictOver(0, lowerBox(0.1, 0.2, 0.0, 0.1), 0.0) == AlphaVerdict::Opaque);

    // Textures: a 4 x 4 checkerboard on the lower triangle with UV = the canonical corners.
    AlphaTable textured;
    const uint32_t map = textured.addMap(checkerboard(4));
    const uint32_t id = textured.addEntry({map, {glm::dvec2(0, 0), glm::dvec2(1, 0), glm::dvec2(1, 1)}});
    CHECK(textured.verdictOver(id, lowerBox(0.55, 0.7, 0.05, 0.2), 0.0) == AlphaVerdict::Opaque);   // texel (2, 0)
    CHECK(textured.verdictOver(id, lowerBox(0.80, 0.95, 0.30, 0.45), 0.0) == AlphaVerdict::Opaque);  // (3, 1)
    CHECK(textured.verdictOver(id, lowerBox(0.80, 0.95, 0.05, 0.2), 0.0) == AlphaVerdict::Clear);    // (3, 0)
    CHECK(textured.verdictOver(id, lowerBox(0.70, 0.80, 0.05, 0.2), 0.0) == AlphaVerdict::Mixed);   // across a texel edge
    // Repeat wraps: u in [1.8, 1.95] is texel 3 again.
    CHECK(textured.verdictOver(id, lowerBox(1.80, 1.95, 0.05, 0.2), 0.0) == AlphaVerdict::Clear);
    // More than 256 texels is not worth judging here: Mixed, even over a uniform map.
    AlphaTable uniform;
    const uint32_t full = uniform.addMap(AlphaMap::texture(64, 64, std::vector<uint8_t>(64 * 64, 1)));
    const uint32_t fullId = uniform.addEntry({full, {glm::dvec2(0, 0), glm::dvec2(1, 0), glm::dvec2(1, 1)}});
    CHECK(uniform.verdictOver(fullId, lowerBox(0.9, 0.95, 0.1, 0.12), 0.0) == AlphaVerdict::Opaque);
    CHECK(uniform.verdictOver(fullId, lowerBox(0.0, 1.0, 0.0, 1.0), 0.0) == AlphaVerdict::Mixed);
}

TEST_CASE("alpha bound: every Opaque or Clear verdict is each hit's own alpha test, for every light kind",
          "[alpha][exact]") {
    const std::vector<Triangle> outlines = leavesAndPetals();
    const ReceiverSet near = randomReceivers(13, 120, {-1.0f, 0, -1.0f}, {1.0f, 0.6f, 1.0f});
    const AlphaSoup soup(5, 12, 0);
    // The soup's textures again, with a max_distance on every id: never Opaque, Clear where the map is.
    auto limited = std::make_shared<AlphaTable>(*soup.table);
    std::vector<Triangle> limitedTris = soup.tris;
    for (Triangle& t : limitedTris)
        if (alphaIdOf(t.flags)) t.flags = withAlphaId(t.flags, limited->withDistance(alphaIdOf(t.flags), 1.5));
    ReceiverSet soupReceivers;
    for (size_t i = 0; i < soup.receivers.size(); i += 4) soupReceivers.position.push_back(soup.receivers.position[i]);

    const std::vector<std::pair<const char*, LightDesc>> lights = {
        {"rect", rectLight({0.3, 4, 0.2}, {1.5, 0, 0}, {0, 0, 1.5}, 1024, 2)},
        {"disk", [] { LightDesc d = diskLight(); d.samples = 512, d.sampleSets = 2; return d; }()},
        {"sphere", [] { LightDesc s = sphereLight(); s.samples = 512, s.sampleSets = 2; return s; }()},
        {"sun", sunLight({0.2, 1, 0.1}, 3.0, 512, 2)}};
    VerdictCounts total;
    for (const auto& [name, light] : lights) {
        INFO(name);
        const LightSamples samples = generateLightSamples({light}, 64, 7);
        for (const VerdictCounts& n : {checkVerdicts(outlines, *AlphaTable::builtin(), samples, near),
                                       checkVerdicts(soup.tris, *soup.table, samples, soupReceivers),
                                       checkVerdicts(limitedTris, *limited, samples, soupReceivers)}) {
            total.opaque += n.opaque, total.clear += n.clear, total.mixed += n.mixed, total.hitsChecked += n.hitsChecked;
            CHECK(n.opaque + n.clear > 0);
        }
    }
    INFO(total.opaque << " opaque, " << total.clear << " clear, " << total.mixed << " mixed, " << total.hitsChecked
                      << " hits checked");
    CHECK(total.opaque > 100);
    CHECK(total.clear > 100);
    CHECK(total.hitsChecked > 10000);
}

TEST_CASE("alpha bound: the light crossing the triangle's plane leaves the group Mixed", "[alpha]") {
    // A leaf standing up through the light: the rect light lies on both sides of its plane.
    const Triangle leaf{{glm::vec3(-0.5f, 1, 0), glm::vec3(0.5f, 1, 0), glm::vec3(0.5f, 5, 0)}, withAlphaId(0, kAlphaLeafLower)};
    const LightSamples samples = generateLightSamples({rectLight({0, 4, 0}, {1, 0, 0}, {0, 0, 1}, 64, 1)}, 64, 7);
    const BlockerTriangle t = BlockerTriangle::from(leaf);
    CHECK(alphaOverBound(*AlphaTable::builtin(), t, {0, 0, -0.5}, samples.groups[0].bound) == AlphaVerdict::Mixed);
}

TEST_CASE("alpha bound: hpc with group verdicts gives the reference's bits and decides groups", "[alpha][hpc][exact]") {
    const std::vector<Triangle> scene = leavesAndPetals();
    ReceiverSet receivers = randomReceivers(17, 300, {-1.2f, 0, -1.2f}, {1.2f, 0.05f, 1.2f});
    const LightSamples samples = generateLightSamples({rectLight({0.4, 4, 0.1}, {1.0, 0, 0}, {0, 0, 1.0}, 512, 2)}, 64, 7);
    const std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    const VisibilityMasks reference = castReference(samples, receivers, sets, scene, receiverEpsilonOf(CastOptions()));
    REQUIRE(reference.blockedCount() > 0);
    for (bool bounds : {true, false}) {
        CastOptions options;
        options.alphaBounds = bounds;
        CastStats stats;
        const VisibilityMasks hpc = castHpc(samples, receivers, sets, scene, options, 1, 97, &stats);
        INFO("alpha bounds " << bounds << ": " << stats.alphaGroupsDecided << " of " << stats.alphaGroupTests << " decided");
        CHECK(hpc.words == reference.words);
        CHECK((stats.alphaGroupsDecided > 0) == bounds);
        CHECK(stats.alphaTests > 0);
    }
}

TEST_CASE("alpha outlines four lanes at once: the scalar alpha test's verdict in every lane", "[alpha][simd]") {
    if (!simdSupported(SimdLevel::Avx2)) {
        WARN("no AVX2 on this CPU: nothing to compare");
        return;
    }
    const HardShadowKernels avx2 = hardShadowKernels(SimdLevel::Avx2);
    Rng rng(29);
    AlphaTable table;
    uint64_t compared = 0, opaque = 0, centroid = 0;
    for (int round = 0; round < 400; ++round) {
        // A leaf or petal map with a random transform, on a triangle with random corner UVs.
        AlphaMap m;
        m.shape = round % 2 ? AlphaShape::Leaf : AlphaShape::Petal;
        const double angle = rng.uniform(-1, 1), s = rng.uniform(0.5, 2);
        m.transform = {s * std::cos(angle), -s * std::sin(angle), rng.uniform(-0.5, 0.5),
                       s * std::sin(angle), s * std::cos(angle), rng.uniform(-0.5, 0.5)};
        if (round % 5 == 0) m.transform = {1, 0, 0, 0, 1, 0};
        AlphaEntry entry{table.addMap(m), {}};
        for (glm::dvec2& uv : entry.uv) uv = {rng.uniform(-0.2, 1.2), rng.uniform(-0.2, 1.2)};
        const uint32_t id = table.addEntry(entry);
        AlphaOutline outline;
        REQUIRE(table.outlineOf(id, outline));
        Triangle raw{{randomIn(rng, {-1, 1, -1}, {1, 2, 1}), randomIn(rng, {-1, 1, -1}, {1, 2, 1}), randomIn(rng, {-1, 1, -1}, {1, 2, 1})},
                     withAlphaId(0, id)};
        const BlockerTriangle t = BlockerTriangle::from(raw);
        if (!t.valid) continue;
        glm::vec3 samples[4];
        for (glm::vec3& l : samples) l = randomIn(rng, {-1.5f, 4, -1.5f}, {1.5f, 4.5f, 1.5f});
        HardShadowBlock block;
        avx2.build(block, samples, 4, 1.0, t);
        for (int receiver = 0; receiver < 8; ++receiver) {
            const glm::dvec3 r(randomIn(rng, {-2, 0, -2}, {2, 0.8f, 2}));
            const EdgeOffsets at(t, r);
            const uint32_t lanes = 0xF;
            const uint32_t got = outlineLanesAvx2(block, lanes, at, outline);
            for (int i = 0; i < 4; ++i) {
                if (block.side[i] == 0.0) continue;
                const double e[3] = {laneEdgeValue(block, 0, i, at), laneEdgeValue(block, 1, i, at), laneEdgeValue(block, 2, i, at)};
                const bool expected = alphaAtEdges(table, t, r, e).opaque;
                INFO("round " << round << ", receiver " << receiver << ", lane " << i);
                REQUIRE(((got >> i) & 1u) == uint32_t(expected));
                ++compared, opaque += expected, centroid += !((e[0] + e[1]) + e[2] > 0.0);
            }
        }
    }
    CHECK(compared > 5000);
    CHECK(opaque > compared / 20);
    CHECK(opaque < compared - compared / 20);
    CHECK(centroid > 0);
    // An id with a max_distance, a texture or no alpha is not an outline: the scalar test keeps it.
    AlphaOutline unused;
    CHECK_FALSE(table.outlineOf(table.withDistance(kAlphaLeafLower, 1.0), unused));
    CHECK_FALSE(table.outlineOf(table.addEntry({table.addMap(AlphaMap::texture(1, 1, {1})), {}}), unused));
    CHECK_FALSE(table.outlineOf(0, unused));
}
