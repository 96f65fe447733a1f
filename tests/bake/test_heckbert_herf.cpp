// Heckbert & Herf's accumulated hard shadows (--method hh) on a lightmapped floor, against the
// closed-form penumbra of a square and of a straight edge, and against the reference. The texel
// receivers here lie at their texel centres on the floor, where hh samples its hard shadows, so
// hh and the reference differ only where a sample's segment passes within roundoff of a blocker
// edge; against the continuous light both are within the stratified samples' bound (one column
// of strata straddles an edge: 1/sqrt(K)).

#include "TestScenes.h"

#include "bake/methods/HeckbertHerf.h"
#include "bake/peers/ReferenceCaster.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// A floor [-2, 2]^2 at y = 0 as two polygons mapped onto a side x side lightmap, with one
/// receiver at each texel centre.
struct LightmappedFloor {
    ReceiverSet receivers;
    ReceiverPolygons polygons;
    std::vector<Triangle> triangles;  ///< the floor itself, which casts nothing on itself
};

LightmappedFloor lightmappedFloor(int side) {
    LightmappedFloor f;
    const glm::dvec3 c[4] = {{-2, 0, -2}, {2, 0, -2}, {2, 0, 2}, {-2, 0, 2}};
    const glm::dvec2 t[4] = {{0, 0}, {double(side), 0}, {double(side), double(side)}, {0, double(side)}};
    const int tri[2][3] = {{0, 2, 1}, {0, 3, 2}};  // wound so the normal points up
    for (const auto& k : tri) {
        ReceiverPolygon p;
        for (int i = 0; i < 3; ++i) p.position[i] = c[k[i]], p.texel[i] = t[k[i]];
        f.polygons.polygons.push_back(p);
        f.triangles.push_back({{glm::vec3(c[k[0]]), glm::vec3(c[k[1]]), glm::vec3(c[k[2]])}, 0});
    }
    for (int y = 0; y < side; ++y)
        for (int x = 0; x < side; ++x) {
            const double u = (x + 0.5) / side, v = (y + 0.5) / side;
            f.receivers.position.push_back({float(-2 + 4 * u), 0.f, float(-2 + 4 * v)});
            f.receivers.normal.push_back({0, 1, 0});
            f.polygons.polygonOf.push_back(u > v ? 0 : 1);  // the diagonal from (0, 0) to (side, side)
            f.polygons.texelOf.push_back({x, y});
        }
    return f;
}

/// hh on the floor under @p blockers: every receiver within the stratification bound of @p exact,
/// and the masks the reference's up to a few relations.
template <class Exact>
void requireHhProfile(const LightDesc& light, std::vector<Triangle> blockers, Exact exact) {
    LightmappedFloor f = lightmappedFloor(64);
    blockers.insert(blockers.end(), f.triangles.begin(), f.triangles.end());
    const LightSamples samples = generateLightSamples({light}, 64, 5);
    const std::vector<uint32_t> sets = assignSets(f.receivers, samples.sets);
    const ReceiverEpsilon eps = receiverEpsilonOf(CastOptions());
    VectorSource source(blockers);
    HeckbertHerfStats stats;
    const VisibilityMasks hh = castHeckbertHerf(samples, f.receivers, sets, source, eps, f.polygons, &stats);
    const VisibilityMasks reference = castReference(samples, f.receivers, sets, blockers, eps);
    CHECK(stats.polygons == 2);
    CHECK(stats.coveredTexels > 0);
    int penumbra = 0;
    for (size_t r = 0; r < f.receivers.size(); ++r) {
        const glm::dvec3 p(f.receivers.position[r]);
        const double v = hh.visibleFraction(r, samples), e = exact(p);
        INFO("receiver (" << p.x << ", " << p.z << "): hh " << v << ", exact " << e);
        CHECK(std::abs(v - e) <= 2.0 / std::sqrt(double(light.samples)) + 1e-6);
        penumbra += e > 0.1 && e < 0.9;
    }
    CHECK(penumbra > 50);
    uint64_t differ = 0;
    for (size_t i = 0; i < hh.words.size(); ++i) differ += uint64_t(__builtin_popcountll(hh.words[i] ^ reference.words[i]));
    CHECK(double(differ) <= 1e-4 * double(f.receivers.size()) * samples.sampleCount);
}

}  // namespace

TEST_CASE("hh: a square over a lightmapped floor, against its closed-form penumbra", "[hh]") {
    // Light 1 x 1 at height 4, occluder [-0.5, 0.5]^2 at height 2: from (x, 0, z) the occluder
    // projects onto the light plane as [-x - 1, -x + 1] x [-z - 1, -z + 1], so the blocked
    // fraction is the product of the overlaps with [-0.5, 0.5] on each axis.
    const LightDesc light = rectLight({0, 4, 0}, {1, 0, 0}, {0, 0, 1}, 256, 4);
    std::vector<Triangle> quad;
    addQuad(quad, {-0.5f, 2, -0.5f}, {0.5f, 2, -0.5f}, {0.5f, 2, 0.5f}, {-0.5f, 2, 0.5f});
    auto overlap = [](double c) { return std::clamp(std::min(0.5, -c + 1) - std::max(-0.5, -c - 1), 0.0, 1.0); };
    requireHhProfile(light, quad, [&](const glm::dvec3& p) { return 1.0 - overlap(p.x) * overlap(p.z); });
}

TEST_CASE("hh: an open floor lit from below is lit, and a square under it shadows it as from above", "[hh]") {
    // The square's scene mirrored under the floor, whose receivers still face up: every sample is
    // behind the polygon's plane. The paper's back-face test counted them all blocked (V = 0
    // everywhere), where the reference blocks only the square's shadow: nothing closes the floor.
    const LightDesc light = rectLight({0, -4, 0}, {0, 0, 1}, {1, 0, 0}, 256, 4);  // facing up
    std::vector<Triangle> quad;
    addQuad(quad, {-0.5f, -2, -0.5f}, {0.5f, -2, -0.5f}, {0.5f, -2, 0.5f}, {-0.5f, -2, 0.5f});
    auto overlap = [](double c) { return std::clamp(std::min(0.5, -c + 1) - std::max(-0.5, -c - 1), 0.0, 1.0); };
    requireHhProfile(light, quad, [&](const glm::dvec3& p) { return 1.0 - overlap(p.x) * overlap(p.z); });
}

TEST_CASE("hh: a closed box's top lit from below is shadowed by the box's own bottom", "[hh]") {
    // The floor as the top of a box [-2, 2] x [-1, 0] x [-2, 2]: from a light under it every
    // segment to the top crosses the bottom face first, which hh now projects (it is on the
    // samples' side of the top's plane), as the reference blocks it.
    LightmappedFloor f = lightmappedFloor(32);
    std::vector<Triangle> blockers = f.triangles;
    addQuad(blockers, {-2, -1, -2}, {2, -1, -2}, {2, -1, 2}, {-2, -1, 2});
    const LightSamples samples = generateLightSamples({rectLight({0, -4, 0}, {0, 0, 1}, {1, 0, 0}, 64, 4)}, 64, 5);
    const std::vector<uint32_t> sets = assignSets(f.receivers, samples.sets);
    const ReceiverEpsilon eps = receiverEpsilonOf(CastOptions());
    VectorSource source(blockers);
    const VisibilityMasks hh = castHeckbertHerf(samples, f.receivers, sets, source, eps, f.polygons, nullptr);
    const VisibilityMasks reference = castReference(samples, f.receivers, sets, blockers, eps);
    double hhVisible = 0;
    for (size_t r = 0; r < f.receivers.size(); ++r) {
        CHECK(reference.visibleFraction(r, samples) == 0.0);
        hhVisible += hh.visibleFraction(r, samples);
    }
    CHECK(hhVisible == 0.0);
}

TEST_CASE("hh: a straight edge gives the analytic penumbra profile", "[hh]") {
    // The profile of tests/test_radiometry.cpp: light x in [-0.5, 0.5] at H = 4, a half-plane
    // blocker over x < 0 at h = 2: V = clamp(0.5 + x).
    const LightDesc light = rectLight({0, 4, 0}, {1, 0, 0}, {0, 0, 0.6}, 256, 4);
    std::vector<Triangle> blocker;
    addQuad(blocker, {-50, 2, -50}, {0, 2, -50}, {0, 2, 50}, {-50, 2, 50});
    requireHhProfile(light, blocker, [](const glm::dvec3& p) { return std::clamp(0.5 + p.x, 0.0, 1.0); });
}

TEST_CASE("hh: a cut-out leaf shadows the lightmap with its outline, as the reference does", "[hh][alpha]") {
    // The built-in leaf outline on a 2 x 2 quad at height 2 (corners (0,0) (1,0) (1,1) (0,1) at
    // x = 2u - 1, z = 2v - 1) under a 1 x 1 light at height 4. hh tests the outline at the point
    // where each texel's segment to each sample meets the card, so its masks are the reference's
    // but for relations within roundoff of the outline or a blocker edge.
    LightmappedFloor f = lightmappedFloor(64);
    std::vector<Triangle> blockers = f.triangles;
    const glm::vec3 p[4] = {{-1, 2, -1}, {1, 2, -1}, {1, 2, 1}, {-1, 2, 1}};
    blockers.push_back({{p[0], p[1], p[2]}, withAlphaId(0, kAlphaLeafLower)});
    blockers.push_back({{p[0], p[2], p[3]}, withAlphaId(0, kAlphaLeafUpper)});
    const LightSamples samples = generateLightSamples({rectLight({0, 4, 0}, {1, 0, 0}, {0, 0, 1}, 64, 4)}, 64, 5);
    const std::vector<uint32_t> sets = assignSets(f.receivers, samples.sets);
    const ReceiverEpsilon eps = receiverEpsilonOf(CastOptions());
    const VisibilityMasks reference = castReference(samples, f.receivers, sets, blockers, eps);
    auto differing = [&](const AlphaTable* alpha) {
        VectorSource source(blockers);
        const VisibilityMasks hh = castHeckbertHerf(samples, f.receivers, sets, source, eps, f.polygons, nullptr, {}, alpha);
        uint64_t differ = 0;
        for (size_t i = 0; i < hh.words.size(); ++i) differ += uint64_t(__builtin_popcountll(hh.words[i] ^ reference.words[i]));
        return double(differ) / (double(f.receivers.size()) * samples.sampleCount);
    };
    const double cutOut = differing(AlphaTable::builtin().get()), opaque = differing(nullptr);
    INFO("relations differing from the reference: with the outline " << cutOut << ", as an opaque quad " << opaque);
    CHECK(cutOut <= 1e-4);
    CHECK(opaque >= 0.05);
}
