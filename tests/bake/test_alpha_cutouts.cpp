// Alpha-tested (cut-out) blockers: the alpha table's texel rule, the barycentrics the rule takes
// from its edge values, and hpc, reference and Embree agreeing on cut-outs (random textured quad
// soups, an analytic checkerboard, cut-outs mixed with opaque blockers, umbra safety).

#include "AlphaScenes.h"
#include "MethodChecks.h"
#include "TestScenes.h"

#include "bake/peers/EmbreeCaster.h"
#include "bake/rule/AlphaRule.h"
#include "bake/rule/TieClassifier.h"
#include "procedural/FlowerGenerator.h"
#include "procedural/TreeGenerator.h"
#include "stream/AlphaTable.h"
#include "stream/Transform.h"
#include "stream/TriangleSource.h"

#include <catch2/catch.hpp>

#include <glm/gtc/matrix_transform.hpp>

#include <atomic>
#include <cmath>

using namespace penumbra;
using namespace penumbra::test;

TEST_CASE("alpha table: nearest texel, wrap modes, transform and outlines", "[alpha]") {
    AlphaTable table;
    AlphaMap m = AlphaMap::texture(4, 2, {1, 0, 0, 0, 0, 0, 0, 1});  // texels (0,0) and (3,1) opaque
    const uint32_t repeat = table.addMap(m);
    m.wrapS = m.wrapT = AlphaWrap::Clamp;
    const uint32_t clamp = table.addMap(m);
    m.wrapS = m.wrapT = AlphaWrap::Mirror;
    const uint32_t mirror = table.addMap(m);
    // Barycentrics (1, 0, 0) put the hit on corner 0, so the entry's uv0 is the looked-up uv.
    auto at = [&](uint32_t map, double u, double v) { return table.lookup(table.addEntry({map, {glm::dvec2(u, v), {}, {}}}), 1, 0, 0); };
    CHECK(at(repeat, 0.1, 0.2).opaque);
    CHECK_FALSE(at(repeat, 0.3, 0.2).opaque);
    CHECK(at(repeat, 0.9, 0.9).opaque);
    CHECK(at(repeat, 1.1, 1.2).opaque);    // wraps to (0.1, 0.2)
    CHECK(at(repeat, -0.1, -0.1).opaque);  // wraps to (0.9, 0.9)
    CHECK(at(clamp, -5.0, -5.0).opaque);   // texel (0, 0)
    CHECK(at(clamp, 7.0, 3.0).opaque);     // texel (3, 1)
    CHECK_FALSE(at(clamp, -5.0, 3.0).opaque);
    CHECK(at(mirror, -0.1, -0.2).opaque);  // mirrors to (0.1, 0.2)
    CHECK(at(mirror, 1.1, 1.1).opaque);    // mirrors to (0.9, 0.9)
    CHECK_FALSE(at(mirror, 1.9, 1.1).opaque);
    CHECK(at(repeat, 0.25, 0.2).tie);      // on the edge between texels 0 and 1
    CHECK_FALSE(at(repeat, 0.3, 0.2).tie);
    // The transform: u' = u + 0.5 moves texel 2 onto u = 0.1 ... 0.25.
    AlphaMap shifted = AlphaMap::texture(4, 1, {0, 0, 1, 0});
    shifted.transform = {1, 0, 0.5, 0, 1, 0};
    CHECK(at(table.addMap(shifted), 0.1, 0.5).opaque);
    // Built-in outlines on the canonical quad: the leaf is opaque along its midrib, not at its tips' sides.
    CHECK(table.lookup(kAlphaLeafLower, 0.5, 0.25, 0.25).opaque);  // uv (0.5, 0.25): inside
    CHECK_FALSE(table.lookup(kAlphaLeafLower, 0.05, 0.95, 0.0).opaque);  // uv (0.95, 0): a corner
    CHECK(table.lookup(kAlphaPetalUpper, 1.0 / 3, 1.0 / 3, 1.0 / 3).opaque);
    CHECK_FALSE(table.lookup(kAlphaPetalUpper, 0.0, 0.0, 1.0).opaque);  // uv (0, 1): a corner
    CHECK(table.lookup(0, 0, 0, 0).opaque);  // no alpha id: opaque
}

TEST_CASE("alpha rule: the barycentrics from the edge values are the hit's", "[alpha]") {
    Rng rng(3);
    int blocked = 0;
    for (int i = 0; i < 2000; ++i) {
        Triangle tri;
        for (auto& v : tri.v) v = randomIn(rng, {-1, 1, -1}, {1, 2, 1});
        const BlockerTriangle t = BlockerTriangle::from(tri);
        const glm::dvec3 l(randomIn(rng, {-1, 4, -1}, {1, 5, 1})), r(randomIn(rng, {-1, 0, -1}, {1, 0, 1}));
        const HardShadowVolume h = makeHardShadowVolume(l, 1.0, t);
        if (!blocks(h, t, r, distanceBehind(t, r), 1e-6)) continue;
        ++blocked;
        const double e[3] = {edgeValue(h, t, 0, r), edgeValue(h, t, 1, r), edgeValue(h, t, 2, r)};
        const double s = e[0] + e[1] + e[2];
        const glm::dvec3 b(e[1] / s, e[2] / s, e[0] / s);
        // The hit point by plain ray-plane intersection.
        const double sl = t.side(l, 1.0), sr = distanceBehind(t, r);
        const glm::dvec3 hit = l + (r - l) * (sl / (sl - sr));
        const glm::dvec3 fromBary = b.x * t.v[0] + b.y * t.v[1] + b.z * t.v[2];
        CHECK(glm::length(hit - fromBary) < 1e-9);
    }
    CHECK(blocked > 100);
}

TEST_CASE("alpha: a checkerboard quad gives its analytic visibility in hpc, reference and Embree", "[alpha][hpc][embree]") {
    auto table = std::make_shared<AlphaTable>();
    const uint32_t n = 8;
    const uint32_t map = table->addMap(checkerboard(n));
    std::vector<Triangle> tris;
    // The quad [-1, 1]^2 at y = 1, uv = ((x + 1) / 2, (z + 1) / 2).
    addAlphaQuad(tris, *table, map, {{-1, 1, -1}, {1, 1, -1}, {1, 1, 1}, {-1, 1, 1}}, {{0, 0}, {1, 0}, {1, 1}, {0, 1}});
    ReceiverSet receivers = randomReceivers(9, 600, {-1.5f, 0, -1.5f}, {1.5f, 0, 1.5f});
    for (auto& nrm : receivers.normal) nrm = {0, 1, 0};
    const LightSamples samples = generateLightSamples({rectLight({0, 3, 0}, {0.6, 0, 0}, {0, 0, 0.6}, 64, 2)}, 64, 7);
    const std::vector<uint32_t> sets = assignSets(receivers, samples.sets);

    // The analytic answer: the segment meets y = 1 at a point whose checker cell decides.
    VisibilityMasks analytic(receivers.size(), samples.groupCount());
    std::vector<uint8_t> nearEdge(receivers.size() * samples.sampleCount, 0);
    for (size_t r = 0; r < receivers.size(); ++r)
        for (int k = 0; k < samples.groupCount(); ++k) {
            const LightSampleGroup& g = samples.groups[k];
            for (uint32_t j = 0; j < g.count; ++j) {
                const glm::dvec3 l(samples.position(int(sets[r]), int(g.first + j))), p(receivers.position[r]);
                const double s = (1.0 - p.y) / (l.y - p.y);
                const double x = p.x + s * (l.x - p.x), z = p.z + s * (l.z - p.z);
                const double cu = (x + 1) / 2 * n, cv = (z + 1) / 2 * n;
                if (std::abs(cu - std::round(cu)) < 1e-6 || std::abs(cv - std::round(cv)) < 1e-6)
                    nearEdge[r * samples.sampleCount + g.first + j] = 1;
                if (x < -1 || x > 1 || z < -1 || z > 1) continue;
                const int i = std::min(int(n) - 1, int(std::floor(cu))), jj = std::min(int(n) - 1, int(std::floor(cv)));
                if ((i + jj) % 2 == 0) analytic.row(r)[k] |= 1ull << j;
            }
        }
    const ReceiverEpsilon eps = receiverEpsilonOf(CastOptions());
    const VisibilityMasks reference = castReference(samples, receivers, sets, tris, eps, {}, *table);
    const VisibilityMasks embree = castEmbree(samples, receivers, sets, tris, eps, nullptr, {}, true, table.get());
    const VisibilityMasks hpc = castHpc(samples, receivers, sets, tris, withTable(CastOptions(), table));
    uint64_t differ = 0;
    for (size_t r = 0; r < receivers.size(); ++r)
        for (int k = 0; k < samples.groupCount(); ++k)
            for (uint32_t j = 0; j < samples.groups[k].count; ++j) {
                const bool a = (analytic.row(r)[k] >> j) & 1, b = (reference.row(r)[k] >> j) & 1;
                if (a != b && !nearEdge[r * samples.sampleCount + samples.groups[k].first + j]) ++differ;
            }
    CHECK(differ == 0);
    CHECK(analytic.blockedCount() > 0);
    CHECK(analytic.blockedCount() < uint64_t(receivers.size()) * samples.sampleCount / 2);
    CHECK(hpc.words == reference.words);
    CHECK(embree.words == reference.words);
}

TEST_CASE("alpha: random textured quad soups, alone and mixed with opaque blockers, agree in every method",
          "[alpha][hpc][embree]") {
    for (int opaque : {0, 40}) {
        const AlphaSoup soup(11 + opaque, 40, opaque);
        const LightSamples samples = generateLightSamples({rectLight({0.3, 4, 0.2}, {1.5, 0, 0}, {0, 0, 1.5}, 128, 4)}, 64, 7);
        const std::vector<uint32_t> sets = assignSets(soup.receivers, samples.sets);
        const ReceiverEpsilon eps = receiverEpsilonOf(CastOptions());
        const VisibilityMasks reference = castReference(samples, soup.receivers, sets, soup.tris, eps, {}, *soup.table);
        // The same scene without alpha blocks strictly more.
        std::vector<Triangle> solid = soup.tris;
        for (Triangle& t : solid) t.flags = 0;
        const VisibilityMasks opaqueRef = castReference(samples, soup.receivers, sets, solid, eps);
        INFO("opaque blockers " << opaque << ": " << reference.blockedCount() << " blocked, " << opaqueRef.blockedCount()
                                << " without alpha");
        REQUIRE(reference.blockedCount() > 0);
        CHECK(reference.blockedCount() < opaqueRef.blockedCount());
        for (size_t i = 0; i < reference.words.size(); ++i) CHECK((reference.words[i] & ~opaqueRef.words[i]) == 0);
        for (const auto& [name, options] : optionVariants())
            for (int tiles : {1, 3}) {
                INFO(name << ", tiles " << tiles);
                CastStats stats;
                const VisibilityMasks hpc = castHpc(samples, soup.receivers, sets, soup.tris, withTable(options, soup.table), tiles, 97, &stats);
                CHECK(hpc.words == reference.words);
                CHECK(stats.alphaRejected > 0);
            }
        // Embree with its filter: the same bits up to classified ties.
        const VisibilityMasks embree = castEmbree(samples, soup.receivers, sets, soup.tris, eps, nullptr, {}, true, soup.table.get());
        const TieClassifier classifier(soup.tris, eps, TieClassifier::kDefaultUlps, soup.table);
        uint64_t mismatches = 0, nonTies = 0;
        for (size_t r = 0; r < soup.receivers.size(); ++r)
            for (int k = 0; k < samples.groupCount(); ++k) {
                const uint64_t diff = embree.row(r)[k] ^ reference.row(r)[k];
                for (uint64_t d = diff; d; d &= d - 1) {
                    const int j = __builtin_ctzll(d);
                    const LightSampleGroup& g = samples.groups[k];
                    ++mismatches;
                    const RelationVerdict v = classifier.classify(glm::dvec3(samples.position(int(sets[r]), int(g.first + j))),
                                                                  samples.w(g.light), glm::dvec3(soup.receivers.position[r]));
                    if (!v.tie) ++nonTies, UNSCOPED_INFO(v.describe());
                }
            }
        CHECK(nonTies == 0);
        CHECK(mismatches * 10000 <= uint64_t(soup.receivers.size()) * samples.sampleCount);
    }
}

TEST_CASE("alpha: umbra safety, an opaque blocker behind a cut-out still makes umbra, the cut-out alone never",
          "[alpha][hpc]") {
    auto table = std::make_shared<AlphaTable>();
    const uint32_t map = table->addMap(checkerboard(64));  // texels far smaller than the light seen through them
    std::vector<Triangle> cutout, both;
    addAlphaQuad(cutout, *table, map, {{-3, 2, -3}, {3, 2, -3}, {3, 2, 3}, {-3, 2, 3}}, {{0, 0}, {1, 0}, {1, 1}, {0, 1}});
    both = cutout;
    addQuad(both, {-2, 1, -2}, {2, 1, -2}, {2, 1, 2}, {-2, 1, 2});  // opaque, between the cut-out and the floor
    ReceiverSet receivers = randomReceivers(4, 500, {-1, 0, -1}, {1, 0, 1});
    const LightSamples samples = generateLightSamples({rectLight({0, 4, 0}, {0.5, 0, 0}, {0, 0, 0.5}, 64, 2)}, 64, 7);
    const std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    for (bool withOpaque : {false, true}) {
        const std::vector<Triangle>& tris = withOpaque ? both : cutout;
        std::vector<Triangle> sorted = tris;
        sortByAreaDescending(sorted);
        PenumbraCaster caster(samples, receivers, sets, withTable(CastOptions(), table), 1);
        caster.cast(sorted);
        std::atomic<uint64_t> umbra{0}, partial{0};
        caster.finish([&](uint32_t, const uint64_t* words, bool full) {
            if (full) ++umbra;
            else if (words) ++partial;
        });
        INFO("with the opaque quad: " << withOpaque);
        if (withOpaque) {
            CHECK(umbra == receivers.size());
        } else {
            CHECK(umbra == 0);
            CHECK(partial == receivers.size());
        }
        const VisibilityMasks reference =
            castReference(samples, receivers, sets, tris, receiverEpsilonOf(CastOptions()), {}, *table);
        CHECK(castHpc(samples, receivers, sets, tris, withTable(CastOptions(), table)).words == reference.words);
    }
}

TEST_CASE("alpha: tree leaves and flower petals are analytic cut-outs that every method tests the same way",
          "[alpha][procedural][embree]") {
    const std::vector<Triangle> scene = leavesAndPetals();
    ReceiverSet receivers = randomReceivers(5, 700, {-1.2f, 0, -1.2f}, {1.2f, 0.05f, 1.2f});
    const std::vector<LightDesc> lights = {rectLight({0.4, 4, 0.1}, {1.0, 0, 0}, {0, 0, 1.0}, 128, 4)};
    requireMatchesReference("tree and flowers with cut-outs", lights, receivers, scene);
    const LightSamples samples = generateLightSamples(lights, 64, 7);
    const std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    const ReceiverEpsilon eps = receiverEpsilonOf(CastOptions());
    const VisibilityMasks reference = castReference(samples, receivers, sets, scene, eps);
    std::vector<Triangle> solid = scene;
    for (Triangle& t : solid) t.flags = withAlphaId(t.flags, 0);
    CHECK(reference.blockedCount() < castReference(samples, receivers, sets, solid, eps).blockedCount());
    const VisibilityMasks embree = castEmbree(samples, receivers, sets, scene, eps);
    uint64_t mismatches = 0;
    for (size_t i = 0; i < embree.words.size(); ++i) mismatches += __builtin_popcountll(embree.words[i] ^ reference.words[i]);
    CHECK(mismatches * 10000 <= uint64_t(receivers.size()) * samples.sampleCount);
}

TEST_CASE("alpha: a mirroring transform keeps a cut-out's vertex order, so its outline", "[alpha]") {
    std::vector<Triangle> quad;
    const glm::vec3 p[4] = {{0.1f, 1, 0.1f}, {1.9f, 1, 0.3f}, {1.7f, 1, 1.8f}, {0.2f, 1, 1.6f}};
    quad.push_back({{p[0], p[1], p[2]}, withAlphaId(0, kAlphaLeafLower)});
    quad.push_back({{p[0], p[2], p[3]}, 0});  // opaque: swapped, to keep its front side
    TransformedSource mirrored(std::make_unique<VectorSource>(quad), glm::scale(glm::mat4(1.0f), glm::vec3(-1, 1, 1)));
    const std::vector<Triangle> m = readAll(mirrored);
    REQUIRE(m.size() == 2);
    CHECK(m[0].v[1].x == -p[1].x);
    CHECK(m[1].v[1].x == -p[3].x);
    const AlphaTable& table = *AlphaTable::builtin();
    Rng rng(2);
    int opaque = 0;
    for (int i = 0; i < 1000; ++i) {
        const glm::dvec3 l(rng.uniform(0, 2), 3, rng.uniform(0, 2)), r(rng.uniform(0, 2), 0, rng.uniform(0, 2));
        const glm::dvec3 lm(-l.x, l.y, l.z), rm(-r.x, r.y, r.z);
        const bool x = blocksWithAlpha(l, 1.0, r, BlockerTriangle::from(quad[0]), ReceiverEpsilon{}, table);
        CHECK(x == blocksWithAlpha(lm, 1.0, rm, BlockerTriangle::from(m[0]), ReceiverEpsilon{}, table));
        opaque += x;
    }
    CHECK(opaque > 100);
}

TEST_CASE("alpha: ssv tests cut-outs as the reference does, leaves and petals among opaque blockers",
          "[alpha][ssv][exact]") {
    // Cut-outs are no silhouette casters: before issue #17's fix ssv cast them as opaque
    // triangles and blocked every relation through a transparent part of a leaf or a petal.
    std::vector<Triangle> scene = leavesAndPetals();
    const std::vector<Triangle> opaque = triangleSoup(21, 30, {-1, 0.3f, -1}, {1, 1.2f, 1}, 0.15f);
    scene.insert(scene.end(), opaque.begin(), opaque.end());
    ReceiverSet receivers = randomReceivers(5, 700, {-1.2f, 0, -1.2f}, {1.2f, 0.05f, 1.2f});
    addReceiversOnTriangles(receivers, opaque, 22, 4);
    requireSsvMatchesReference("leaves, petals and opaque soup", {rectLight({0.4, 4, 0.1}, {1.0, 0, 0}, {0, 0, 1.0}, 128, 4)},
                               receivers, scene);
    requireSsvMatchesReference("leaves, petals and opaque soup under a sun", {sunLight({0.45, -1, 0.3}, 4.0, 64)}, receivers, scene);
}

TEST_CASE("alpha: ssv tests textured cut-out quad soups as the reference does", "[alpha][ssv][exact]") {
    for (int opaque : {0, 40}) {
        INFO("opaque blockers " << opaque);
        const AlphaSoup soup(11 + opaque, 40, opaque);
        requireSsvMatchesReference("textured alpha soup", {rectLight({0.3, 4, 0.2}, {1.5, 0, 0}, {0, 0, 1.5}, 128, 4)},
                                   soup.receivers, soup.tris, 64, receiverEpsilonOf(CastOptions()), soup.table);
    }
}
