// Penumbra maps (--method penumbra-map, Wyman & Hansen 2003) against closed-form penumbrae: a
// square over a floor and a straight edge. The method is approximate by design: its umbra is the
// hard shadow from the light's centre and its penumbra only the outer half. Two checks:
//  - against the paper's own profile in closed form: past the hard-shadow edge, at a tangent
//    offset a from the silhouette seen from the centre, the cone reaches Z_F = Z_v / (1 - a Z_v / L_r),
//    I = (Z_F - Z_v) / (Z_P - Z_v) and V = 3 I^2 - 2 I^3 (within the texels' aliasing);
//  - against the exact profile: the documented bound |V - V_exact| <= 0.6 for these
//    configurations (h / H = 1/2), exact in the umbra and beyond the outer edge.

#include "TestScenes.h"

#include "bake/methods/PenumbraMap.h"
#include "bake/shading/ReceiverShading.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// Receivers on the floor along x in [-2, 2] at z = 0, normals up.
ReceiverSet floorLine(int count) {
    ReceiverSet r;
    for (int i = 0; i < count; ++i) {
        r.position.push_back({float(-2.0 + 4.0 * i / (count - 1)), 0.f, 0.f});
        r.normal.push_back({0, 1, 0});
    }
    return r;
}

std::vector<float> penumbraMapOf(const LightDesc& light, const ReceiverSet& receivers, std::vector<Triangle> blockers,
                                 int resolution = 1024) {
    const LightSamples samples = generateLightSamples({light}, 64, 3);
    VectorSource source(std::move(blockers));
    PenumbraMapOptions options;
    options.resolution = resolution;
    return castPenumbraMap(samples, receivers, {}, source, receiverEpsilonOf(CastOptions()), options);
}

/// The paper's outer penumbra at distance @p d (world units on the floor) past the hard-shadow
/// edge, for a light of half-width 0.5 at height 4 and a silhouette at height 2 seen from
/// straight above: a = d / 4, Z_F = 2 / (1 - d), I = d / (1 - d).
double paperProfile(double d) {
    if (d <= 0) return 0.0;
    if (d >= 0.5) return 1.0;
    const double i = d / (1.0 - d);
    return i * i * (3 - 2 * i);
}

/// Both checks of the file comment; @p past(x) is how far x lies past the hard-shadow edge.
template <class Exact, class Past>
void requireProfiles(const ReceiverSet& receivers, const std::vector<float>& v, Exact exact, Past past) {
    int penumbra = 0;
    for (size_t i = 0; i < receivers.size(); ++i) {
        const double x = receivers.position[i].x, e = exact(x), d = past(x);
        INFO("x = " << x << ": penumbra map " << v[i] << ", exact " << e << ", paper " << paperProfile(d));
        CHECK(std::abs(v[i] - e) <= 0.6);
        if (std::abs(d) > 0.01) CHECK(std::abs(v[i] - paperProfile(d)) <= 0.05);
        if (e == 0.0 || (e == 1.0 && std::abs(exact(x + 0.03) - exact(x - 0.03)) == 0.0)) CHECK(std::abs(v[i] - e) <= 0.02);
        penumbra += e > 0.1 && e < 0.9;
    }
    CHECK(penumbra > 10);
}

}  // namespace

TEST_CASE("penumbra map: a square over a floor, against its closed-form penumbra", "[penumbra-map]") {
    // Light: 1 x 1 at height 4. Occluder: [-0.5, 0.5]^2 at height 2. From a floor point (x, 0, 0)
    // the occluder projects onto the light plane as [-x - 1, -x + 1] x [-1, 1]: V = clamp(|x| - 0.5).
    const LightDesc light = rectLight({0, 4, 0}, {1, 0, 0}, {0, 0, 1}, 256, 1);
    std::vector<Triangle> quad;
    addQuad(quad, {-0.5f, 2, -0.5f}, {0.5f, 2, -0.5f}, {0.5f, 2, 0.5f}, {-0.5f, 2, 0.5f});
    std::vector<Triangle> floor = floorQuad(4);
    quad.insert(quad.end(), floor.begin(), floor.end());
    const ReceiverSet receivers = floorLine(401);
    const std::vector<float> v = penumbraMapOf(light, receivers, quad);
    auto exact = [](double x) { return std::clamp(std::abs(x) - 0.5, 0.0, 1.0); };
    // The hard shadow from the centre covers |x| < 1; beyond it the outer penumbra rises from 0
    // to 1 at |x| = 1.5, where the exact penumbra ends too, and never falls.
    requireProfiles(receivers, v, exact, [](double x) { return std::abs(x) - 1.0; });
    for (size_t i = 1; i < receivers.size(); ++i)
        if (receivers.position[i].x > 0) CHECK(v[i] >= v[i - 1] - 1e-6f);
}

TEST_CASE("penumbra map: a straight edge gives the outer half of the analytic profile", "[penumbra-map]") {
    // The profile of tests/test_radiometry.cpp: light x in [-0.5, 0.5] at H = 4, a half-plane
    // blocker over x < 0 at h = 2; exact V = clamp(0.5 + x).
    const LightDesc light = rectLight({0, 4, 0}, {1, 0, 0}, {0, 0, 0.6}, 256, 1);
    std::vector<Triangle> blocker;
    addQuad(blocker, {-50, 2, -50}, {0, 2, -50}, {0, 2, 50}, {-50, 2, 50});
    std::vector<Triangle> floor = floorQuad(4);
    blocker.insert(blocker.end(), floor.begin(), floor.end());
    const ReceiverSet receivers = floorLine(201);
    const std::vector<float> v = penumbraMapOf(light, receivers, blocker);
    auto exact = [](double x) { return std::clamp(0.5 + x, 0.0, 1.0); };
    requireProfiles(receivers, v, exact, [](double x) { return x; });
    for (size_t i = 0; i < receivers.size(); ++i)
        if (receivers.position[i].x < -0.01) CHECK(v[i] == 0.0f);  // the hard shadow from the centre
}

TEST_CASE("penumbra map: irradiance is the unoccluded irradiance times the visible fraction", "[penumbra-map][radiometry]") {
    LightDesc a = rectLight({-1, 3, 0}, {1, 0, 0}, {0, 0, 1}, 64, 2), b = rectLight({2, 2, 0}, {0.5, 0, 0}, {0, 0, 0.5}, 64, 2);
    b.radiance = {0, 3, 0};
    const std::vector<LightDesc> lights = {a, b};
    const ReceiverSet receivers = randomReceivers(3, 20, {-2, -1, -2}, {2, 0, 2});
    const LightSamples samples = generateLightSamples(lights, 64, 11);
    const std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    ReceiverShader shader(lights, samples, receivers, sets);
    ReceiverResults full, scaled;
    full.resize(receivers.size(), 2), scaled.resize(receivers.size(), 2);
    for (uint32_t r = 0; r < receivers.size(); ++r) {
        shader.shade(r, nullptr, false, full);
        const float v[2] = {0.25f, 1.0f};
        shader.shadeVisibleFraction(r, v, scaled);
        CHECK(scaled.irradianceOf(r, 0).x == Approx(0.25 * full.irradianceOf(r, 0).x));
        CHECK(scaled.irradianceOf(r, 1).y == Approx(full.irradianceOf(r, 1).y));
        CHECK(scaled.visibility[r] == Approx((0.25 * 64 + 64) / 128.0));
    }
}
