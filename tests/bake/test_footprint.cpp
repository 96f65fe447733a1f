// Footprints of split blockers (SampleMaskTable::footprint()): every sample the blocking rule
// finds blocked lies in the box, for both the scalar and the AVX2 bound, including receivers
// placed so that blocked samples sit on the footprint's edges and receivers level with a vertex.

#include "TestScenes.h"

#include "bake/cast/SampleMaskTable.h"
#include "bake/rule/BlockingRule.h"

#include <catch2/catch.hpp>

using namespace penumbra;
using namespace penumbra::test;

namespace {

struct FootprintTally {
    uint64_t boxes = 0, unknown = 0, none = 0;
    uint64_t blocked = 0;   ///< samples the rule blocks (all inside their box)
    uint64_t excluded = 0;  ///< samples a box excludes (the test's point: it excludes many)
    uint64_t inside = 0;
};

/// Every sample of every set of receiver @p r against split blocker @p t, from footprint() and
/// from footprints() (a leaf chunk of four: r in lanes 0, 1 and 3 with other sets, lane 2 on T).
void checkFootprint(const LightSamples& samples, const SampleMaskTable& table, const BlockerTriangle& t, const glm::dvec3& r,
                    FootprintTally& tally) {
    const ReceiverEpsilon epsilon = receiverEpsilonOf(CastOptions());
    const SampleMaskTable::Blocker b = table.prepare(t);
    if (!b.split) return;
    const double dist = distanceBehind(t, r), eps = epsilon.at(r), w = samples.w(0);
    const uint32_t sets = uint32_t(samples.sets);
    const glm::dvec3 onT = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
    const glm::dvec3 chunk[4] = {r, r, onT, r};
    const uint32_t chunkSet[4] = {0, 1 % sets, 0, 2 % sets};
    const double chunkDist[4] = {dist, dist, distanceBehind(t, onT), dist};
    const double chunkEps[4] = {eps, eps, epsilon.at(onT), eps};
    SampleMaskTable::FootprintResult chunkResult[4];
    SampleMaskTable::Footprint chunkFootprint[4];
    table.footprints(b, chunk, chunkSet, chunkDist, chunkEps, 0xF, chunkResult, chunkFootprint);
    CHECK(chunkResult[2] == SampleMaskTable::FootprintResult::NoneBlocked);
    for (uint32_t set = 0; set < sets + 3; ++set) {
        SampleMaskTable::Footprint f;
        SampleMaskTable::FootprintResult result;
        uint32_t of = set;
        if (set < sets) {
            result = table.footprint(b, set, r, dist, eps, f);
        } else {  // the chunk's lanes 0, 1 and 3
            const int lane = set == sets ? 0 : set == sets + 1 ? 1 : 3;
            result = chunkResult[lane], f = chunkFootprint[lane], of = chunkSet[lane];
        }
        tally.boxes += result == SampleMaskTable::FootprintResult::Box;
        tally.unknown += result == SampleMaskTable::FootprintResult::Unknown;
        tally.none += result == SampleMaskTable::FootprintResult::NoneBlocked;
        if (result == SampleMaskTable::FootprintResult::Unknown) continue;
        for (uint32_t k = 0; k < uint32_t(samples.groupCount()); ++k) {
            const LightSampleGroup& group = samples.groups[k];
            const uint64_t word = result == SampleMaskTable::FootprintResult::Box ? f.word(k) : 0;
            for (uint32_t j = 0; j < group.count; ++j) {
                const bool blocked = blocks(glm::dvec3(samples.position(int(of), int(group.first + j))), w, r, t, epsilon);
                const bool in = (word >> j) & 1;
                if (blocked && !in) {
                    INFO("set " << of << (set >= sets ? " (chunk)" : "") << " group " << k << " sample " << j << " receiver " << r.x << " " << r.y << " " << r.z);
                    FAIL("a blocked sample outside the footprint");
                }
                tally.blocked += blocked, tally.excluded += !in, tally.inside += in;
            }
        }
    }
}

/// Upright blades, thin walls seen from beside (the bars' faces of GRIDS) and a wall standing on
/// the receivers' floor, against receivers at random, beside the walls' bases and on lines from a
/// sample through an edge.
FootprintTally checkLight(const LightDesc& light, SimdLevel simd) {
    const LightSamples samples = generateLightSamples({light}, 64, 3);
    const SampleMaskTable table(samples, 0, 64, 64, simd);
    REQUIRE(table.usable());
    std::vector<Triangle> tris;
    Rng rng(41);
    for (int i = 0; i < 24; ++i) {
        const glm::vec3 base = randomIn(rng, {-1.5f, 0.3f, -1.5f}, {1.5f, 1.5f, 1.5f});
        tris.push_back({{base, base + randomIn(rng, {-0.3f, 0, -0.3f}, {0.3f, 0, 0.3f}), base + glm::vec3(0.1f, 3.0f, 0.05f)}, 0});
        // A long thin face: 3 m by 4 cm, its plane upright.
        const float along = i % 2 ? 1.0f : 0.0f;
        const glm::vec3 a = base, d = glm::vec3(3.0f * along, 0, 3.0f * (1 - along)), h(0, 0.04f, 0);
        tris.push_back({{a, a + d, a + d + h}, 0});
        tris.push_back({{a, a + d + h, a + h}, 0});
    }
    tris.push_back({{glm::vec3(-2.25f, 0, -5.25f), glm::vec3(-2.25f, 0, -4.75f), glm::vec3(-2.25f, 3.65f, -4.75f)}, 0});
    FootprintTally tally;
    for (const Triangle& tri : tris) {
        const BlockerTriangle t = BlockerTriangle::from(tri);
        if (!t.valid) continue;
        checkFootprint(samples, table, t, (t.v[0] + t.v[1] + t.v[2]) / 3.0, tally);  // on T: nothing blocked
        for (int i = 0; i < 12; ++i) checkFootprint(samples, table, t, glm::dvec3(glm::vec3(randomIn(rng, {-3, -0.5f, -3}, {3, 0.2f, 3}))), tally);
        for (int i = 0; i < 4; ++i) {  // beside the base, a hair below its level (a floor's hit points)
            const glm::dvec3 r = t.v[i % 3] + glm::dvec3(rng.uniform(-0.3, 0.3), -3e-8 * rng.uniform(), rng.uniform(-1.5, 0.3));
            checkFootprint(samples, table, t, glm::dvec3(glm::vec3(r)), tally);
        }
        for (int i = 0; i < 6; ++i) {  // on the line from a sample through a vertex or an edge point
            const glm::dvec3 l(samples.position(int(rng.next() % uint64_t(samples.sets)), int(rng.next() % uint64_t(samples.sampleCount))));
            const int e = int(rng.next() % 3);
            const double s = i < 2 ? 0.0 : rng.uniform();
            const glm::dvec3 onEdge = t.v[e] + s * (t.v[(e + 1) % 3] - t.v[e]);
            const glm::dvec3 away = samples.w(0) == 0.0 ? -glm::normalize(l) : onEdge - l;
            checkFootprint(samples, table, t, glm::dvec3(glm::vec3(onEdge + (0.2 + rng.uniform()) * away)), tally);
        }
    }
    return tally;
}

}  // namespace

TEST_CASE("a split blocker's footprint holds every sample the rule blocks", "[table][footprint][exact]") {
    LightDesc sun;
    sun.type = LightType::Sun, sun.direction = {0.3, -1, 0.2}, sun.angularDiameterDeg = 8, sun.samples = 64, sun.sampleSets = 4;
    const std::vector<std::pair<std::string, LightDesc>> lights = {
        {"rect", rectLight({0, 4, 0}, {1.3, 0.2, 0}, {0, 0.1, 1.1}, 64, 4)},
        {"large rect", rectLight({0, 4, 0}, {4, 0, 0}, {0, 0, 4}, 256, 2)},
        {"disk", diskLight()},
        {"polygon", polygonLight()},
        {"sun", sun},
    };
    std::vector<SimdLevel> levels = {SimdLevel::Scalar};
    if (simdSupported(SimdLevel::Avx2)) levels.push_back(SimdLevel::Avx2);
    for (const auto& [name, light] : lights)
        for (const SimdLevel simd : levels) {
            const FootprintTally tally = checkLight(light, simd);
            INFO(name << (simd == SimdLevel::Avx2 ? " avx2" : " scalar") << ": boxes " << tally.boxes << ", unknown " << tally.unknown
                      << ", none blocked " << tally.none << ", blocked " << tally.blocked << ", excluded " << tally.excluded
                      << ", inside " << tally.inside);
            CHECK(tally.blocked > 0);
            CHECK(tally.none > 0);
            // The point of a footprint: most pairs get a box, and it leaves out most samples.
            CHECK(tally.boxes > 2 * tally.unknown);
            CHECK(tally.excluded > 2 * tally.inside);
        }
}
