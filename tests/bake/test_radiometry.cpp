// Radiometry: irradiance against Lambert's polygon form factor, a straight edge's penumbra
// against its analytic visible fraction, power-to-radiance, and the sun light (placement,
// irradiance, and bit-exact hpc vs reference casting).

#include "TestScenes.h"

#include "bake/shading/ReceiverShading.h"
#include "bake/peers/ReferenceCaster.h"
#include "bake/light/SunLight.h"

#include <catch2/catch.hpp>

#include <glm/gtc/constants.hpp>
#include <glm/trigonometric.hpp>

#include <cmath>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// Lambert's formula for the irradiance at p (normal n) from a uniform Lambertian polygon of
/// radiance L wholly above p's horizon: E = L/2 * |sum_i angle_i * (n . gamma_i)|, gamma_i the unit
/// normal of the plane through p and edge i.
double lambertIrradiance(const std::vector<glm::dvec3>& poly, glm::dvec3 p, glm::dvec3 n, double L) {
    double sum = 0;
    for (size_t i = 0; i < poly.size(); ++i) {
        glm::dvec3 a = glm::normalize(poly[i] - p), b = glm::normalize(poly[(i + 1) % poly.size()] - p);
        double angle = std::acos(std::clamp(glm::dot(a, b), -1.0, 1.0));
        sum += angle * glm::dot(n, glm::normalize(glm::cross(a, b)));
    }
    return 0.5 * L * std::abs(sum);
}

ReceiverResults shadeUnoccluded(const std::vector<LightDesc>& lights, const ReceiverSet& receivers) {
    LightSamples samples = generateLightSamples(lights, 64, 11);
    std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    ReceiverShader shader(lights, samples, receivers, sets);
    ReceiverResults out;
    out.resize(receivers.size(), int(lights.size()));
    for (uint32_t r = 0; r < receivers.size(); ++r) shader.shade(r, nullptr, false, out);
    return out;
}

LightDesc sun(glm::dvec3 direction, double diameterDeg, int samples = 64) {
    LightDesc l;
    l.type = LightType::Sun, l.direction = direction, l.angularDiameterDeg = diameterDeg;
    l.irradiance = {1000, 900, 800}, l.samples = samples, l.sampleSets = 4, l.where = "sun";
    return l;
}

}  // namespace

TEST_CASE("unoccluded irradiance from a rect light matches Lambert's form factor", "[radiometry]") {
    LightDesc rect = rectLight({0, 3, 0}, {1.2, 0, 0}, {0, 0, 0.8}, 1024, 1);
    rect.radiance = {2.0, 1.0, 0.5};
    std::vector<glm::dvec3> corners;
    for (auto [a, b] : {std::pair{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}})
        corners.push_back(rect.center + a * rect.u + b * rect.v);
    ReceiverSet receivers;
    // Positions below the light, at several heights and offsets; tilts keep the light above the horizon.
    for (glm::dvec3 p : {glm::dvec3(0, 0, 0), {0.7, 1, -0.4}, {-1.5, 0.5, 0.3}, {0.2, 2, 0.1}})
        for (glm::dvec3 n : {glm::dvec3(0, 1, 0), {0.3, 1, 0}, {-0.2, 1, 0.4}, {0, 1, -0.5}}) {
            receivers.position.push_back(glm::vec3(p));
            receivers.normal.push_back(glm::vec3(glm::normalize(n)));
        }
    ReceiverResults out = shadeUnoccluded({rect}, receivers);
    for (size_t i = 0; i < receivers.size(); ++i) {
        glm::dvec3 p(receivers.position[i]), n(receivers.normal[i]);
        for (int c = 0; c < 3; ++c) {
            double expected = lambertIrradiance(corners, p, n, rect.radiance[c]);
            INFO("receiver " << i << " channel " << c << ": " << out.irradiance[i][c] << " vs " << expected);
            CHECK(std::abs(out.irradiance[i][c] - expected) <= 0.005 * expected);
        }
        CHECK(out.visibility[i] == 1.f);
    }
}

TEST_CASE("unoccluded irradiance from a disk light matches the on-axis closed form", "[radiometry]") {
    // A disk of radius a and radiance L, facing a receiver on its axis at distance h that faces
    // it: E = pi L a^2 / (a^2 + h^2). (A disk's area once read 0, so disks lit nothing.)
    LightDesc disk;
    disk.type = LightType::Disk, disk.center = {0, 3, 0}, disk.normal = {0, -1, 0}, disk.radius = 0.8;
    disk.radiance = {2.0, 1.0, 0.5}, disk.samples = 1024, disk.sampleSets = 1, disk.where = "disk";
    CHECK(disk.area() == Approx(glm::pi<double>() * 0.64));
    ReceiverSet receivers;
    for (double y : {0.0, 1.0, 2.5}) {
        receivers.position.push_back(glm::vec3(0, float(y), 0));
        receivers.normal.push_back(glm::vec3(0, 1, 0));
    }
    ReceiverResults out = shadeUnoccluded({disk}, receivers);
    for (size_t i = 0; i < receivers.size(); ++i) {
        const double h = 3.0 - double(receivers.position[i].y), a2 = disk.radius * disk.radius;
        for (int c = 0; c < 3; ++c) {
            const double expected = glm::pi<double>() * disk.radiance[c] * a2 / (a2 + h * h);
            INFO("receiver " << i << " channel " << c << ": " << out.irradiance[i][c] << " vs " << expected);
            CHECK(std::abs(out.irradiance[i][c] - expected) <= 0.01 * expected);
        }
    }
    // "power" on a disk: radiance = P / (pi area), finite.
    const glm::dvec3 radiance = radianceFromPower(disk, glm::dvec3(100.0));
    CHECK(radiance.x == Approx(100.0 / (glm::pi<double>() * disk.area())));
}

TEST_CASE("a straight occluder edge gives the analytic penumbra profile", "[radiometry]") {
    // Light spans x in [-0.5, 0.5] at height H; a half-plane blocker covers x < 0 at height h.
    const double H = 4, h = 2, w = 1;
    LightDesc rect = rectLight({0, H, 0}, {w, 0, 0}, {0, 0, 0.6}, 1024, 1);
    std::vector<Triangle> blocker;
    addQuad(blocker, {-50, float(h), -50}, {0, float(h), -50}, {0, float(h), 50}, {-50, float(h), 50});
    ReceiverSet receivers;
    for (int i = 0; i <= 60; ++i) {
        receivers.position.push_back({float(-1.5 + 3.0 * i / 60), 0.f, 0.f});
        receivers.normal.push_back({0, 1, 0});
    }
    LightSamples samples = generateLightSamples({rect}, 64, 5);
    std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    VisibilityMasks masks = castReference(samples, receivers, sets, blocker, receiverEpsilonOf(CastOptions{}));
    ReceiverShader shader({rect}, samples, receivers, sets);
    ReceiverResults out;
    out.resize(receivers.size(), 1);
    bool sawPenumbra = false;
    for (uint32_t r = 0; r < receivers.size(); ++r) {
        shader.shade(r, masks.row(r), false, out);
        double x = receivers.position[r].x;
        // Visible iff the ray to light point lx crosses y = h at x >= 0: lx >= -x (H - h) / h.
        double expected = std::clamp((w / 2 + x * (H - h) / h) / w, 0.0, 1.0);
        sawPenumbra |= expected > 0.1 && expected < 0.9;
        INFO("x = " << x);
        // Stratified samples: at most one column of 32 strata straddles the edge.
        CHECK(std::abs(out.visibility[r] - expected) <= 1.0 / 32 + 1e-6);
    }
    CHECK(sawPenumbra);
}

TEST_CASE("several lights give per-light visibility and irradiance that sum to the totals", "[radiometry]") {
    LightDesc a = rectLight({-1, 3, 0}, {1, 0, 0}, {0, 0, 1}, 256, 2);
    LightDesc b = rectLight({2, 2, 0}, {0.5, 0, 0}, {0, 0, 0.5}, 64, 2);
    b.radiance = {0, 3, 0};
    ReceiverSet receivers = randomReceivers(3, 50, {-2, -1, -2}, {2, 0, 2});
    ReceiverResults out = shadeUnoccluded({a, b}, receivers);
    REQUIRE(out.lightVisibility.size() == 100);
    for (size_t r = 0; r < receivers.size(); ++r) {
        glm::vec3 sum = out.irradianceOf(r, 0) + out.irradianceOf(r, 1);
        CHECK(std::abs(sum.y - out.irradiance[r].y) <= 1e-5f * (1 + out.irradiance[r].y));
        CHECK(out.irradianceOf(r, 0).y == Approx(out.irradianceOf(r, 0).x));
        CHECK(out.irradianceOf(r, 1).x == 0.f);
        CHECK(out.visibilityOf(r, 0) == 1.f);
        CHECK(out.visibilityOf(r, 1) == 1.f);
    }
}

/// E at p (unit normal n) from a sphere of radiance L: L times the integral of max(cos, 0) over
/// the cone it subtends, by a fine midpoint rule in the cone's own polar coordinates.
double sphereIrradiance(glm::dvec3 centre, double radius, glm::dvec3 p, glm::dvec3 n, double L) {
    const glm::dvec3 axis = glm::normalize(centre - p);
    const glm::dvec3 u = glm::normalize(glm::cross(axis, std::abs(axis.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0)));
    const glm::dvec3 v = glm::cross(axis, u);
    const double cosMax = std::sqrt(1 - radius * radius / glm::dot(centre - p, centre - p));
    const int rings = 400, sectors = 800;
    double sum = 0;
    for (int i = 0; i < rings; ++i) {
        const double c = 1 - (1 - cosMax) * (i + 0.5) / rings, s = std::sqrt(1 - c * c);
        for (int j = 0; j < sectors; ++j) {
            const double phi = glm::two_pi<double>() * (j + 0.5) / sectors;
            sum += std::max(0.0, glm::dot(n, c * axis + s * (std::cos(phi) * u + std::sin(phi) * v)));
        }
    }
    return L * glm::two_pi<double>() * (1 - cosMax) * sum / (double(rings) * sectors);
}

TEST_CASE("a sphere light is a uniformly bright sphere, near or far and across the horizon", "[radiometry]") {
    // Samples uniform in the ball crowded the cone's centre: E was 12 % low with the centre on the
    // receiver's horizon at four radii, 3 % high facing it at 1.1 radii.
    LightDesc sphere;
    sphere.type = LightType::Sphere, sphere.center = {0, 2, 0}, sphere.radius = 0.5, sphere.samples = 4096;
    sphere.sampleSets = 1, sphere.radiance = glm::dvec3(1.0);
    ReceiverSet receivers;
    const double tilts[] = {0, 1.0, glm::half_pi<double>(), 2.0, 2.09};
    const double distances[] = {0.55, 0.8, 2.0, 5.0};
    for (double d : distances)
        for (double tilt : tilts) {
            receivers.position.push_back(glm::vec3(0, 2 - d, 0));
            receivers.normal.push_back(glm::vec3(std::sin(tilt), std::cos(tilt), 0));
        }
    const ReceiverResults out = shadeUnoccluded({sphere}, receivers);
    for (size_t r = 0; r < receivers.size(); ++r) {
        const double expected = sphereIrradiance(sphere.center, sphere.radius, glm::dvec3(receivers.position[r]),
                                                 glm::normalize(glm::dvec3(receivers.normal[r])), 1.0);
        INFO("receiver " << r << " at " << receivers.position[r].y << ", expected " << expected);
        // 4096 stratified samples: within 2 % of the value, plus 0.2 % of the facing value there.
        // At a tenth of the radius from the surface, the few samples nearest the receiver carry
        // large 1/d^2 weights, and the noise is a few percent (uniform in the ball: 20 % low).
        const double d = 2.0 - receivers.position[r].y, facing = glm::pi<double>() * 0.25 / (d * d);
        const double relative = d < 0.6 ? 0.07 : 0.02;
        CHECK(std::abs(out.irradiance[r].x - expected) <= relative * expected + 0.002 * facing);
        CHECK(out.visibility[r] == 1.0f);
    }
}

TEST_CASE("power converts to radiance by the emitter's area", "[radiometry]") {
    LightDesc rect = rectLight({0, 3, 0}, {2, 0, 0}, {0, 0, 0.5}, 16, 1);
    glm::dvec3 L = radianceFromPower(rect, glm::dvec3(glm::pi<double>()));
    CHECK(L.x == Approx(1.0));
    LightDesc sphere;
    sphere.type = LightType::Sphere, sphere.radius = 0.5;
    CHECK(radianceFromPower(sphere, glm::dvec3(4 * glm::pi<double>() * glm::pi<double>() * 0.25)).y == Approx(1.0));
    CHECK_THROWS_AS(radianceFromPower(sun({0, -1, 0}, 0.53), glm::dvec3(1)), InputError);
}

TEST_CASE("a surface facing a wide sun receives the irradiance given", "[sun][radiometry]") {
    // The samples' mean cosine to the axis was left in: 0.99235 of the irradiance at 20 degrees.
    for (double diameter : {0.53, 5.0, 20.0}) {
        LightDesc s = sun({0.3, -1, 0.2}, diameter, 1024);
        ReceiverSet receivers;
        receivers.position.push_back({0.f, 0.f, 0.f});
        receivers.normal.push_back(glm::vec3(-glm::normalize(s.direction)));
        const ReceiverResults out = shadeUnoccluded({s}, receivers);
        INFO("diameter " << diameter);
        CHECK(out.irradiance[0].x == Approx(1000).epsilon(2e-5));
        const double t = std::tan(glm::radians(diameter) / 2);
        CHECK(sunMeanCosine(diameter) == Approx(2 * (std::sqrt(1 + t * t) - 1) / (t * t)).epsilon(1e-9));
    }
}

TEST_CASE("a sun's samples are directions and give irradiance x cos", "[sun][radiometry]") {
    LightDesc s = sun({0.3, -1, 0.2}, 0.53, 256);
    std::vector<LightDesc> placed = {s};
    glm::dvec3 dir = glm::normalize(s.direction);
    LightSamples samples = generateLightSamples(placed, 64, 1);
    CHECK(samples.w(0) == 0.0);
    CHECK(samples.lightBounds[0].directional());
    for (const glm::vec3& d : samples.positions) {  // within the cone, on the plane at unit distance
        const glm::dvec3 x(d);
        CHECK(glm::dot(x, -dir) == Approx(1.0).epsilon(1e-6));
        CHECK(std::acos(glm::dot(glm::normalize(x), -dir)) <= 0.5 * glm::radians(0.53) * (1 + 1e-6));
    }

    ReceiverSet receivers;
    for (glm::dvec3 n : {glm::dvec3(0, 1, 0), -dir, {1, 0.2, 0}, {0, 0.5, 1}}) {
        receivers.position.push_back({0.5f, 0.f, -0.3f});
        receivers.normal.push_back(glm::vec3(glm::normalize(n)));
    }
    ReceiverResults out = shadeUnoccluded(placed, receivers);
    for (size_t r = 0; r < receivers.size(); ++r) {
        double c = std::max(0.0, glm::dot(glm::dvec3(receivers.normal[r]), -dir));
        INFO("receiver " << r);
        CHECK(out.irradiance[r].x == Approx(1000 * c).margin(1e-3).epsilon(1e-4));
        CHECK(out.irradiance[r].z == Approx(800 * c).margin(1e-3).epsilon(1e-4));
    }
    // Radiance given instead: irradiance = L * pi * sin^2(half angle).
    double half = 0.5 * glm::radians(0.53);
    CHECK(sunIrradianceFromRadiance(glm::dvec3(1), 0.53).x == Approx(glm::pi<double>() * std::sin(half) * std::sin(half)));
}

TEST_CASE("sun shadows from hpc match the reference bit for bit", "[sun][hpc][exact]") {
    std::vector<Triangle> tris = triangleSoup(21, 50, {-2, 0.5f, -2}, {2, 2.5f, 2}, 1.0f);
    std::vector<Triangle> floor;
    addQuad(floor, {-4, 0, -4}, {4, 0, -4}, {4, 0, 4}, {-4, 0, 4});
    ReceiverSet receivers;
    addReceiversOnTriangles(receivers, floor, 22, 400);
    addReceiversOnTriangles(receivers, tris, 23, 2);
    tris.insert(tris.end(), floor.begin(), floor.end());
    for (double diameter : {0.53, 6.0}) {
        std::vector<LightDesc> lights = {sun({0.4, -1, 0.25}, diameter, 128)};
        LightSamples samples = generateLightSamples(lights, 64, 7);
        std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
        VisibilityMasks reference = castReference(samples, receivers, sets, tris, receiverEpsilonOf(CastOptions{}));
        INFO("diameter " << diameter << ": " << reference.blockedCount() << " blocked");
        REQUIRE(reference.blockedCount() > 0);
        REQUIRE(reference.blockedCount() < uint64_t(receivers.size()) * samples.sampleCount);
        // Some receivers must be in partial shadow, or the penumbra volumes prove little.
        ReceiverShader shader(lights, samples, receivers, sets);
        ReceiverResults out;
        out.resize(receivers.size(), 1);
        int partial = 0;
        for (uint32_t r = 0; r < receivers.size(); ++r) {
            shader.shade(r, reference.row(r), false, out);
            partial += out.visibility[r] > 0 && out.visibility[r] < 1;
        }
        CHECK(partial > 0);
        for (const auto& [name, options] : optionVariants()) {
            INFO(name);
            VisibilityMasks hpc = castHpc(samples, receivers, sets, tris, options, 2);
            CHECK(hpc.words == reference.words);
        }
    }
}

TEST_CASE("irradiance from blocked-sample masks equals the sum over the visible samples", "[radiometry]") {
    // Group sizes that are not multiples of 64 (100 and 37 samples) put groups at any bit offset
    // of the visible-sample mask; several lights put them at any group index.
    LightDesc a = rectLight({-1, 3, 0}, {1.5, 0, 0}, {0, 0.3, 1}, 100, 3);
    LightDesc b = polygonLight();
    b.samples = 37;
    LightDesc c = rectLight({1, 2.5, 0.5}, {0.4, 0, 0}, {0, 0, 0.4}, 256, 2);
    const std::vector<LightDesc> lights = {a, b, c};
    const LightSamples samples = generateLightSamples(lights, 24, 7);
    ReceiverSet receivers = randomReceivers(5, 300, {-2, -1, -2}, {2, 0, 2});
    for (size_t r = 0; r < receivers.size(); ++r)  // some receivers facing away from some lights
        if (r % 7 == 3) receivers.normal[r] = glm::normalize(glm::vec3(1, 0.2f, -0.3f));
    const std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    ReceiverShader shader(lights, samples, receivers, sets);
    ReceiverResults out;
    out.resize(receivers.size(), int(lights.size()));
    Rng rng(9);
    double largest = 0;
    for (uint32_t r = 0; r < receivers.size(); ++r) {
        std::vector<uint64_t> words(size_t(samples.groupCount()));
        for (size_t k = 0; k < words.size(); ++k) words[k] = rng.next() & rng.next() & samples.groups[k].fullMask();  // a quarter blocked
        if (r % 5 == 0) words.assign(words.size(), 0);           // nothing blocked
        if (r % 11 == 0)                                         // all blocked
            for (size_t k = 0; k < words.size(); ++k) words[k] = samples.groups[k].fullMask();
        shader.shade(r, words.data(), false, out);
        const glm::dvec3 p(receivers.position[r]), n(receivers.normal[r]);
        for (int li = 0; li < int(lights.size()); ++li) {
            // The rule's sum, independently: radiance x area / K x cos cos / d^2 per visible sample.
            const LightDesc& l = lights[size_t(li)];
            const glm::dvec3 emitter = l.emitterNormal();
            double sum = 0;
            for (uint32_t k = samples.lightFirstGroup[li]; k < samples.lightFirstGroup[li + 1]; ++k) {
                const LightSampleGroup& g = samples.groups[k];
                for (uint32_t j = 0; j < g.count; ++j) {
                    if (words[k] >> j & 1u) continue;
                    const glm::dvec3 d = glm::dvec3(samples.position(int(sets[r]), int(g.first + j))) - p;
                    const double d2 = glm::dot(d, d);
                    sum += std::max(0.0, glm::dot(n, d)) * std::max(0.0, -glm::dot(emitter, d)) / (d2 * d2);
                }
            }
            const double expected = l.radiance.x * l.area() / l.samples * sum;
            const double got = out.irradianceOf(r, li).x;
            INFO("receiver " << r << " light " << li << " got " << got << " expected " << expected);
            REQUIRE(std::abs(got - expected) <= 1e-5 * expected + 1e-30);
            largest = std::max(largest, expected);
        }
    }
    CHECK(largest > 0.01);  // real irradiance, not zeros
}
