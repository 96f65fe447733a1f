// Suns at infinity and far area lights: hpc and the reference agree bit for bit, both agree with
// the blocking rule in exact rational arithmetic, and Embree agrees up to classified ties.

#include "RationalRule.h"
#include "TestScenes.h"

#include "bake/peers/EmbreeCaster.h"
#include "bake/rule/TieClassifier.h"
#include "procedural/BoxesGenerator.h"
#include "procedural/GrassGenerator.h"

#include <catch2/catch.hpp>

using namespace penumbra;
using namespace penumbra::test;

namespace {

LightDesc sunLight(glm::dvec3 direction, double diameterDeg, int samples, int sets = 4) {
    LightDesc l;
    l.type = LightType::Sun, l.direction = direction, l.angularDiameterDeg = diameterDeg;
    l.samples = samples, l.sampleSets = sets, l.where = "sun";
    return l;
}

/// A patch of grass blades on a floor, receivers on the floor and on the blades.
void grassScene(std::vector<Triangle>& tris, ReceiverSet& receivers, int blades) {
    GrassParams g;
    g.placement.area = {-1, -1, 1, 1};
    g.placement.count = uint64_t(blades);
    g.seed = 9;
    tris = readAll(*makeGrassSource(g));
    std::vector<Triangle> floor;
    addQuad(floor, {-2, 0, -2}, {2, 0, -2}, {2, 0, 2}, {-2, 0, 2});
    addReceiversOnTriangles(receivers, floor, 31, 500);
    addReceiversOnTriangles(receivers, tris, 32, 1);
    tris.insert(tris.end(), floor.begin(), floor.end());
}

void boxesScene(std::vector<Triangle>& tris, ReceiverSet& receivers) {
    std::vector<BoxShape> boxes = {{{-1, 0, -1}, {-0.4, 0.8, -0.2}}, {{0.2, 0, 0.1}, {0.9, 0.4, 0.7}},
                                   {{-0.3, 0.9, 0.2}, {0.1, 1.1, 0.6}}};
    tris = readAll(*makeBoxSource(boxes));
    std::vector<Triangle> floor;
    addQuad(floor, {-3, 0, -3}, {3, 0, -3}, {3, 0, 3}, {-3, 0, 3});
    addReceiversOnTriangles(receivers, floor, 41, 700);
    addReceiversOnTriangles(receivers, tris, 42, 8);
    tris.insert(tris.end(), floor.begin(), floor.end());
}

/// Could the segment from @p r along @p d (t in [0, t1]) meet @p t? A conservative box test
/// (margin 1e-6 of the coordinates) that spares the exact rule most triangles.
bool nearSegment(const Triangle& t, const glm::dvec3& r, const glm::dvec3& d, double t1) {
    glm::dvec3 lo(t.v[0]), hi(t.v[0]);
    for (const glm::vec3& v : t.v) lo = glm::min(lo, glm::dvec3(v)), hi = glm::max(hi, glm::dvec3(v));
    double t0 = 0.0;
    for (int a = 0; a < 3; ++a) {
        const double m = 1e-6 * std::max({1.0, std::abs(lo[a]), std::abs(hi[a]), std::abs(r[a])});
        if (d[a] == 0.0) {
            if (r[a] < lo[a] - m || r[a] > hi[a] + m) return false;
            continue;
        }
        double ta = (lo[a] - m - r[a]) / d[a], tb = (hi[a] + m - r[a]) / d[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta), t1 = std::min(t1, tb);
        if (t0 > t1) return false;
    }
    return true;
}

/// Reference == exact rational rule on @p count relations chosen at random.
void requireReferenceIsExact(const LightSamples& samples, const ReceiverSet& receivers, const std::vector<uint32_t>& sets,
                             const std::vector<Triangle>& tris, const VisibilityMasks& reference, int count) {
    const ReceiverEpsilon eps = receiverEpsilonOf(CastOptions());
    Rng rng(77);
    int checked = 0, blocked = 0;
    for (int i = 0; i < count; ++i) {
        const uint32_t r = uint32_t(rng.next() % receivers.size());
        const uint32_t k = uint32_t(rng.next() % uint64_t(samples.groupCount()));
        const LightSampleGroup& g = samples.groups[k];
        const uint32_t j = uint32_t(rng.next() % g.count);
        const glm::dvec3 l(samples.position(int(sets[r]), int(g.first + j))), p(receivers.position[r]);
        const double w = samples.w(g.light);
        bool exact = false;
        for (const Triangle& t : tris)
            if (nearSegment(t, p, l - w * p, w == 0.0 ? INFINITY : 1.0) && exactlyBlocks(l, w, p, t, eps.relative, eps.length)) {
                exact = true;
                break;
            }
        INFO("receiver " << r << " group " << k << " sample " << j);
        REQUIRE(bool(reference.row(r)[k] >> j & 1) == exact);
        ++checked, blocked += exact;
    }
    CHECK(blocked > 0);
    CHECK(blocked < checked);
}

/// Embree disagrees with the rule only on classified ties, and never blocks what the rule does not.
void requireEmbreeTies(const LightSamples& samples, const ReceiverSet& receivers, const std::vector<uint32_t>& sets,
                       const std::vector<Triangle>& tris, const VisibilityMasks& reference) {
    const ReceiverEpsilon eps = receiverEpsilonOf(CastOptions());
    VisibilityMasks embree = castEmbree(samples, receivers, sets, tris, eps);
    const TieClassifier classifier(tris, eps);
    uint64_t mismatches = 0;
    for (size_t r = 0; r < receivers.size(); ++r)
        for (int k = 0; k < reference.groups; ++k)
            for (uint64_t diff = reference.row(r)[k] ^ embree.row(r)[k]; diff; diff &= diff - 1) {
                const int j = __builtin_ctzll(diff);
                const LightSampleGroup& g = samples.groups[k];
                const glm::dvec3 l(samples.position(int(sets[r]), int(g.first) + j)), p(receivers.position[r]);
                const RelationVerdict v = classifier.classify(l, samples.w(g.light), p);
                INFO("receiver " << r << " sample " << g.first + j << ": " << v.describe());
                CHECK(v.tie);
                CHECK((reference.row(r)[k] >> j & 1));  // Embree never blocks what the rule does not
                ++mismatches;
            }
    CHECK(double(mismatches) <= 1e-4 * double(receivers.size()) * samples.sampleCount);
}

}  // namespace

TEST_CASE("sun on grass and on boxes: hpc == reference == exact rule, Embree up to ties", "[sun][exact]") {
    for (int scene = 0; scene < 2; ++scene) {
        std::vector<Triangle> tris;
        ReceiverSet receivers;
        if (scene == 0) grassScene(tris, receivers, 120);
        else boxesScene(tris, receivers);
        const std::vector<LightDesc> lights = {sunLight({0.45, -1, 0.3}, scene == 0 ? 0.53 : 4.0, 64)};
        INFO((scene == 0 ? "grass" : "boxes"));
        requireMatchesReference(scene == 0 ? "grass" : "boxes", lights, receivers, tris);
        LightSamples samples = generateLightSamples(lights, 64, 7);
        std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
        VisibilityMasks reference = castReference(samples, receivers, sets, tris, receiverEpsilonOf(CastOptions()));
        requireReferenceIsExact(samples, receivers, sets, tris, reference, 1500);
        requireEmbreeTies(samples, receivers, sets, tris, reference);
    }
}

TEST_CASE("sun: a row of receivers across one blade's shadow edge matches the exact rule", "[sun][exact]") {
    // One grass-blade-sized triangle (2 cm x 30 cm) standing on a floor, a sun with one sample,
    // and 81 receivers across the blade's shadow. With a far triangle, the scene is 50x larger.
    for (bool large : {false, true}) {
        std::vector<Triangle> tris;
        tris.push_back(Triangle{{glm::vec3(0, 0, 0), glm::vec3(0.02f, 0, 0), glm::vec3(0.01f, 0.3f, 0)}});
        addQuad(tris, {-1, 0, -1}, {1, 0, -1}, {1, 0, 1}, {-1, 0, 1});
        if (large) tris.push_back(Triangle{{glm::vec3(50, 0, 50), glm::vec3(51, 0, 50), glm::vec3(50, 1, 50)}});
        const LightDesc sun = sunLight({0.3, -1, 0.5}, 0.53, 1, 1);
        const LightSamples samples = generateLightSamples({sun}, 64, 5);
        const glm::dvec3 d(samples.positions[0]);
        // The shadow of the blade's middle height lies around p + t d; cross it along x.
        const double t = 0.15 / d.y;
        ReceiverSet receivers;
        for (int i = 0; i <= 80; ++i) {
            const double x = 0.01 - t * d.x - 0.02 + 0.04 * i / 80.0, z = -t * d.z;
            receivers.position.push_back(glm::vec3(float(x), 0.0f, float(z)));
            receivers.normal.push_back({0, 1, 0});
        }
        const std::vector<uint32_t> sets(receivers.size(), 0);
        CastOptions options;
        if (large) options.epsilonLength = 50;  // a 50x larger scene's receivers
        const ReceiverEpsilon eps = receiverEpsilonOf(options);
        const VisibilityMasks reference = castReference(samples, receivers, sets, tris, eps);
        const VisibilityMasks hpc = castHpc(samples, receivers, sets, tris, options, 2);
        int blocked = 0;
        for (size_t r = 0; r < receivers.size(); ++r) {
            bool exact = false;
            for (const Triangle& tri : tris) exact = exact || exactlyBlocks(d, 0.0, glm::dvec3(receivers.position[r]), tri, eps.relative, eps.length);
            INFO("receiver " << r << (large ? " (large scene)" : ""));
            CHECK(bool(reference.row(r)[0] & 1) == exact);
            CHECK(bool(hpc.row(r)[0] & 1) == exact);
            blocked += exact;
        }
        CHECK(blocked > 10);
        CHECK(blocked < 71);
    }
}

TEST_CASE("disk and rect lights 1e2, 1e4 and 4e5 scene sizes away give the reference's masks", "[exact][far]") {
    std::vector<Triangle> tris;
    ReceiverSet receivers;
    soupOverFloor(tris, receivers);  // a scene about 8 units across
    const glm::dvec3 towards = glm::normalize(glm::dvec3(0.3, 1, 0.2));
    for (double sizes : {1e2, 1e4, 4e5}) {
        const double distance = 8 * sizes, radius = distance * 0.03;  // about 3.4 degrees across
        LightDesc disk;
        disk.type = LightType::Disk, disk.center = distance * towards, disk.normal = -towards, disk.radius = radius;
        disk.samples = 64, disk.sampleSets = 4, disk.where = "disk";
        const glm::dvec3 u = glm::normalize(glm::cross(towards, glm::dvec3(0, 0, 1))), v = glm::cross(towards, u);
        LightDesc rect = rectLight(distance * towards, 2 * radius * v, 2 * radius * u, 64, 4);
        for (const LightDesc& light : {disk, rect}) {
            INFO(sizes << " scene sizes away, " << light.where);
            requireMatchesReference("far", {light}, receivers, tris);
            LightSamples samples = generateLightSamples({light}, 64, 7);
            std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
            VisibilityMasks reference = castReference(samples, receivers, sets, tris, receiverEpsilonOf(CastOptions()));
            requireReferenceIsExact(samples, receivers, sets, tris, reference, 600);
        }
    }
}
