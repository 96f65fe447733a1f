// The AVX2 leaf prefilter keeps exactly the receivers the scalar tests keep, with the same
// distances, bit for bit (bake/cast/LeafPrefilter.h).

#include "TestScenes.h"

#include "bake/cast/BlockerBatch.h"
#include "bake/cast/LeafPrefilter.h"

#include <catch2/catch.hpp>

#include <cstring>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// Receivers where the tests' outcomes turn: on V_L's planes, on T's plane and within epsilon of
/// it, on T itself, and scattered around it.
std::vector<glm::dvec3> receiversAround(Rng& rng, const PenumbraVolume& v, const BlockerTriangle& t) {
    std::vector<glm::dvec3> out;
    for (int i = 0; i < 24; ++i) out.push_back(glm::dvec3(randomIn(rng, {-4, -3, -4}, {4, 2, 4})));
    for (int j = 0; j < v.count; ++j) {  // projected onto plane j: its value rounds to about 0
        const Plane p = v.plane(j);
        for (int i = 0; i < 3; ++i) {
            const glm::dvec3 q = glm::dvec3(randomIn(rng, {-4, -3, -4}, {4, 2, 4}));
            out.push_back(q - (glm::dot(p.n, q) + p.d) / glm::dot(p.n, p.n) * p.n);
        }
    }
    for (int i = 0; i < 8; ++i) {  // on T, and a hair off its plane on either side
        const double a = rng.uniform(), b = rng.uniform() * (1 - a);
        const glm::dvec3 on = t.v[0] + a * (t.v[1] - t.v[0]) + b * (t.v[2] - t.v[0]);
        out.push_back(on);
        out.push_back(on + 1e-5 * t.plane.n);
        out.push_back(on - 3e-5 * t.plane.n);
    }
    return out;
}

}  // namespace

TEST_CASE("the AVX2 leaf prefilter keeps the scalar one's receivers and distances", "[hpc][simd]") {
    if (!simdSupported(SimdLevel::Avx2)) {
        WARN("no AVX2 on this CPU: nothing to compare");
        return;
    }
    const std::vector<LightDesc> lights = {rectLight({0, 4, 0}, {4, 0, 0}, {0, 0, 4}), sunLight({0.3, -1, 0.2}, 5.0, 16),
                                           diskLight(), polygonLight()};
    const ReceiverEpsilon epsilon = receiverEpsilonOf(CastOptions());
    uint64_t compared = 0, kept = 0, outside = 0, nearPlane = 0;
    for (const LightDesc& light : lights) {
        const LightSamples samples = generateLightSamples({light}, 64, 3);
        for (uint64_t seed = 1; seed <= 30; ++seed) {
            Rng rng(seed);
            Triangle tri = triangleSoup(seed, 1, {-1, 0, -1}, {1, 1, 1}, 1.5f)[0];
            if (seed % 4 == 0) tri.v[1].y = tri.v[2].y = tri.v[0].y;  // level: its plane misses the light
            BlockerTriangle t = BlockerTriangle::from(tri);
            if (!t.valid) continue;
            t.closed = seed % 3 == 0;
            const PenumbraVolume v = makePenumbraVolume(samples.lightBounds[0], t);
            const std::vector<glm::dvec3> receivers = receiversAround(rng, v, t);
            std::vector<double> eps;
            for (const glm::dvec3& r : receivers) eps.push_back(seed % 5 == 0 ? 0.0 : epsilon.at(r));
            for (uint32_t planes : {v.all(), v.all() & 0x55555555u, v.all() & 0xAAAAAAAAu, 0u}) {
                for (size_t r0 = 0; r0 < receivers.size(); r0 += 3) {  // chunks overlap: every lane sees every receiver
                    const int n = int(std::min<size_t>(1 + r0 % 4, receivers.size() - r0));
                    double dist[4];
                    const uint32_t mask = leafPrefilterAvx2(v, planes, t, &receivers[r0], &eps[r0], n, dist);
                    REQUIRE(mask < (1u << n));
                    for (int i = 0; i < n; ++i) {
                        INFO("light " << int(light.type) << " seed " << seed << " receiver " << r0 + i << " planes " << planes);
                        double scalarDist = 0;
                        const bool pass = passesLeafPrefilter(v, planes, t, receivers[r0 + i], eps[r0 + i], scalarDist);
                        REQUIRE(pass == bool(mask >> i & 1));
                        if (pass) REQUIRE(std::memcmp(&scalarDist, &dist[i], sizeof(double)) == 0);
                        ++compared, kept += pass;
                        outside += !contains(v, receivers[r0 + i], planes);
                        const double d = distanceBehind(t, receivers[r0 + i]);
                        nearPlane += !(d > eps[r0 + i]) && !(-d > eps[r0 + i]);
                    }
                }
            }
        }
    }
    INFO(compared << " compared, " << kept << " kept, " << outside << " outside V_L, " << nearPlane << " near T's plane");
    // Every outcome must occur often enough to mean something.
    CHECK(kept > 1000);
    CHECK(outside > 1000);
    CHECK(nearPlane > 100);
    CHECK(compared - kept > 2000);
}

// A closed face's front plane in V_L (BlockerBatch.h, cutInFront()) may cull a box only where
// the leaf prefilter's closed test would skip every receiver in it: each receiver more than its
// own eps(r) in front of T. Boxes are placed across the plane's margin, at scales from 1 to 1e4.
TEST_CASE("a closed face's front plane culls only receivers in front of it", "[hpc]") {
    uint64_t culled = 0, kept = 0, wholeCast = 0;
    for (uint64_t seed = 1; seed <= 400; ++seed) {
        Rng rng(seed);
        const float scale = float(std::pow(10.0, double(seed % 5)));
        Triangle tri = triangleSoup(seed, 1, scale * glm::vec3(-1), scale * glm::vec3(1), 1.5f * scale)[0];
        BlockerTriangle t = BlockerTriangle::from(tri);
        if (!t.valid) continue;
        t.closed = true;
        const Box receivers{scale * glm::vec3(-4), scale * glm::vec3(4)};
        CastOptions options;
        options.epsilonLength = 4.0 * scale;
        const ReceiverEpsilon epsilon = receiverEpsilonOf(options);
        PenumbraVolume v;
        v.count = 0;
        if (!cutInFront(v, t, receivers, largestCoordinate(receivers), options)) {  // never for these boxes: T lies inside them
            ++wholeCast;
            continue;
        }
        REQUIRE(v.frontCulled);
        REQUIRE(v.count == 1);
        const double eps = epsilon.at(glm::dvec3(options.epsilonLength));
        for (int b = 0; b < 64; ++b) {
            // A small box whose nearest corner lies about k eps in front of T's plane.
            const glm::dvec3 q = t.v[0] + rng.uniform(-1, 1) * (t.v[1] - t.v[0]) + rng.uniform(-1, 1) * (t.v[2] - t.v[0]);
            const double k = rng.uniform(0.0, 3.0), size = eps * rng.uniform(0.0, 4.0);
            const glm::vec3 lo = glm::vec3(q + k * eps * t.plane.n - 0.5 * size * glm::abs(t.plane.n));
            const Box box{lo, lo + glm::vec3(float(size))};
            uint32_t active = v.all();
            if (intersects(v, box, active)) {
                ++kept;
                continue;
            }
            ++culled;
            for (int c = 0; c < 8; ++c) {
                const glm::dvec3 r{c & 1 ? box.hi.x : box.lo.x, c & 2 ? box.hi.y : box.lo.y, c & 4 ? box.hi.z : box.lo.z};
                INFO("seed " << seed << " box " << b << " corner " << c);
                REQUIRE(distanceBehind(t, r) > epsilon.at(r));
            }
        }
    }
    INFO(culled << " boxes culled, " << kept << " kept, " << wholeCast << " triangles outside");
    CHECK(culled > 2000);
    CHECK(kept > 2000);
    CHECK(wholeCast == 0);
}

TEST_CASE("a closed face's front plane drops a light when every receiver is in front", "[hpc]") {
    Triangle tri;
    tri.v[0] = {0, 0, 0}, tri.v[1] = {0, 0, 1}, tri.v[2] = {1, 0, 0};  // normal +y
    BlockerTriangle t = BlockerTriangle::from(tri);
    t.closed = true;
    REQUIRE(t.plane.n.y > 0.99);
    CastOptions options;
    const Box above{{-1, 0.5f, -1}, {1, 2, 1}}, across{{-1, -0.5f, -1}, {1, 2, 1}};
    PenumbraVolume v;
    v.count = 0;
    CHECK_FALSE(cutInFront(v, t, above, largestCoordinate(above), options));  // all above: in front
    v.count = 0;
    CHECK(cutInFront(v, t, across, largestCoordinate(across), options));
    CHECK(v.frontCulled);
    v.count = PenumbraVolume::kMaxPlanes, v.frontCulled = false;  // full: nothing appended
    CHECK(cutInFront(v, t, above, largestCoordinate(above), options));
    CHECK_FALSE(v.frontCulled);
}
