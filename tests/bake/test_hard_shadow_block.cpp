// The SIMD hard-shadow kernels decide every relation exactly as the scalar blocking rule does.

#include "TestScenes.h"

#include "bake/cast/HardShadowBlock.h"
#include "stream/util/Error.h"

#include <catch2/catch.hpp>

#include <bit>

using namespace penumbra;
using namespace penumbra::test;

namespace {

std::vector<SimdLevel> supportedLevels() {
    std::vector<SimdLevel> levels;
    for (SimdLevel l : {SimdLevel::Scalar, SimdLevel::Sse2, SimdLevel::Avx2})
        if (simdSupported(l)) levels.push_back(l);
    return levels;
}

/// Samples around a triangle, some exactly in its plane, receivers on both sides and near edges.
struct Case {
    BlockerTriangle t;
    std::vector<glm::vec3> samples;
    std::vector<glm::dvec3> receivers;
};

Case randomCase(uint64_t seed) {
    Rng rng(seed);
    Case c;
    Triangle tri = triangleSoup(seed, 1, {-1, 0, -1}, {1, 1, 1}, 1.5f)[0];
    if (seed % 5 == 0) tri.v[1].y = tri.v[2].y = tri.v[0].y;  // axis-aligned plane: samples can lie in it
    c.t = BlockerTriangle::from(tri);
    for (int i = 0; i < 11; ++i) {
        glm::vec3 s = randomIn(rng, {-2, 2, -2}, {2, 3, 2});
        if (seed % 5 == 0 && i % 3 == 0) s.y = tri.v[0].y;  // in T's plane: blocks nothing
        c.samples.push_back(s);
    }
    for (int i = 0; i < 200; ++i) c.receivers.push_back(glm::dvec3(randomIn(rng, {-3, -2, -3}, {3, 1, 3})));
    for (int i = 0; i < 50; ++i) {  // on the triangle and its edges, where ties live
        double a = rng.uniform(), b = rng.uniform() * (1 - a);
        glm::dvec3 p = c.t.v[0] + a * (c.t.v[1] - c.t.v[0]) + b * (c.t.v[2] - c.t.v[0]);
        c.receivers.push_back(glm::dvec3(glm::vec3(p)));
    }
    return c;
}

}  // namespace

TEST_CASE("every SIMD level decides each relation like the blocking rule", "[hpc][simd]") {
    uint64_t blocked = 0, tested = 0;
    for (uint64_t seed = 1; seed <= 40; ++seed) {
        Case c = randomCase(seed);
        if (!c.t.valid) continue;
        const ReceiverEpsilon eps{1e-5, 1.0};
        // w = 1: the samples are points; w = 0: the same vectors are sun directions.
        for (double w : {1.0, 0.0})
            for (SimdLevel level : supportedLevels()) {
                INFO("seed " << seed << ", " << simdName(level) << ", w " << w);
                HardShadowKernels k = hardShadowKernels(level);
                REQUIRE(k.level == level);
                std::vector<HardShadowBlock> hard(3);  // 11 samples: 4 + 4 + 3, last lane unused
                for (int b = 0; b < 3; ++b)
                    k.build(hard[b], &c.samples[4 * b], std::min(4, int(c.samples.size()) - 4 * b), w, c.t);
                for (const glm::dvec3& r : c.receivers) {
                    const double dist = distanceBehind(c.t, r), e = eps.at(r);
                    const EdgeOffsets at(c.t, r);
                    uint64_t expected = 0;
                    for (size_t i = 0; i < c.samples.size(); ++i)
                        expected |= uint64_t(blocks(glm::dvec3(c.samples[i]), w, r, c.t, eps)) << i;
                    const uint64_t word = k.test(hard.data(), 0b111, at, dist, e);
                    REQUIRE(word == expected);
                    // The alpha test reads the hit's edge values from the blocks: the rule's own doubles.
                    for (size_t i = 0; i < c.samples.size(); ++i) {
                        const HardShadowVolume h = makeHardShadowVolume(glm::dvec3(c.samples[i]), w, c.t);
                        if (h.side == 0.0) continue;
                        for (int edge = 0; edge < 3; ++edge)
                            REQUIRE(std::bit_cast<uint64_t>(laneEdgeValue(hard[i / 4], edge, int(i % 4), at)) ==
                                    std::bit_cast<uint64_t>(edgeValue(h, c.t, edge, r)));
                    }
                    REQUIRE(k.test(hard.data(), 0b010, at, dist, e) == (expected & 0xF0));  // only block 1
                    blocked += __builtin_popcountll(word);
                    tested += c.samples.size();
                }
            }
    }
    // The cases must exercise both outcomes.
    CHECK(blocked > 500);
    CHECK(blocked < tested / 2);
}

TEST_CASE("the AVX2 build gives the scalar planes bit for bit", "[hpc][simd]") {
    if (!simdSupported(SimdLevel::Avx2)) {
        WARN("no AVX2 on this CPU: nothing to compare");
        return;
    }
    HardShadowKernels scalar = hardShadowKernels(SimdLevel::Scalar), avx2 = hardShadowKernels(SimdLevel::Avx2);
    for (uint64_t seed = 1; seed <= 40; ++seed) {
        Case c = randomCase(seed);
        if (!c.t.valid) continue;
        for (double w : {1.0, 0.0}) {
            HardShadowBlock a, b;
            scalar.build(a, c.samples.data(), 3, w, c.t);
            avx2.build(b, c.samples.data(), 3, w, c.t);
            for (int i = 0; i < 4; ++i) {
                INFO("seed " << seed << " lane " << i << " w " << w);
                REQUIRE(a.side[i] == b.side[i]);
                if (a.side[i] == 0.0) continue;  // the edges of a plane-lying sample are never read
                for (int e = 0; e < 3; ++e) {
                    REQUIRE(a.nx[e][i] == b.nx[e][i]);
                    REQUIRE(a.ny[e][i] == b.ny[e][i]);
                    REQUIRE(a.nz[e][i] == b.nz[e][i]);
                }
            }
            CHECK(b.side[3] == 0.0);  // the unused lane blocks nothing
        }
    }
}

TEST_CASE("SIMD level names parse and bad names are rejected", "[simd]") {
    for (SimdLevel l : {SimdLevel::Scalar, SimdLevel::Sse2, SimdLevel::Avx2, SimdLevel::Auto})
        CHECK(parseSimdLevel(simdName(l), "x") == l);
    CHECK_THROWS_AS(parseSimdLevel("avx9", "scene.json: bake.simd"), InputError);
    CHECK(hardShadowKernels(SimdLevel::Auto).level != SimdLevel::Auto);
}

TEST_CASE("blocksHolding marks exactly the blocks with a sample, for every nibble pattern", "[hpc][simd]") {
    // Against the obvious loop, over single bits, whole nibbles and pseudo-random words.
    auto slow = [](uint64_t s) {
        uint32_t which = 0;
        for (int b = 0; b < 16; ++b)
            if ((s >> (4 * b)) & 0xF) which |= 1u << b;
        return which;
    };
    STATIC_REQUIRE(blocksHolding(0) == 0);
    STATIC_REQUIRE(blocksHolding(~0ull) == 0xFFFFu);
    for (int bit = 0; bit < 64; ++bit) CHECK(blocksHolding(1ull << bit) == 1u << (bit / 4));
    uint64_t x = 0x9E3779B97F4A7C15ull;
    for (int i = 0; i < 20000; ++i) {
        x ^= x << 13, x ^= x >> 7, x ^= x << 17;
        const uint64_t sparse = x & (x >> 11) & (x >> 23);  // few bits: most nibbles empty
        REQUIRE(blocksHolding(x) == slow(x));
        REQUIRE(blocksHolding(sparse) == slow(sparse));
    }
}
