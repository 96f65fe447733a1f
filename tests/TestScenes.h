#pragma once
// Shared builders for the casting tests: random blockers, receivers, lights, and a helper that
// runs hierarchical penumbra casting and returns masks in the same layout as the reference.

#include "TestSupport.h"

#include "bake/cast/CastOptions.h"
#include "bake/light/Light.h"
#include "bake/cast/PenumbraCaster.h"
#include "bake/peers/ReferenceCaster.h"
#include "bake/cast/VisibilityMasks.h"
#include "AreaSort.h"
#include "procedural/BoxesGenerator.h"
#include "procedural/GrassGenerator.h"
#include "receivers/ReceiverSet.h"
#include "stream/ObjReader.h"
#include "stream/Transform.h"
#include "stream/util/Random.h"
#include "stream/Triangle.h"

#include <catch2/catch.hpp>
#include <glm/vec2.hpp>
#include <glm/geometric.hpp>

#include <string>
#include <vector>

namespace penumbra::test {

inline glm::vec3 randomIn(Rng& rng, glm::vec3 lo, glm::vec3 hi) {
    return {float(rng.uniform(lo.x, hi.x)), float(rng.uniform(lo.y, hi.y)), float(rng.uniform(lo.z, hi.z))};
}

/// Random triangles of varied size inside a box.
inline std::vector<Triangle> triangleSoup(uint64_t seed, int count, glm::vec3 lo, glm::vec3 hi, float maxEdge) {
    Rng rng(seed);
    std::vector<Triangle> out;
    for (int i = 0; i < count; ++i) {
        glm::vec3 c = randomIn(rng, lo, hi);
        float s = maxEdge * float(0.1 + 0.9 * rng.uniform());
        Triangle t;
        for (auto& v : t.v) v = c + s * randomIn(rng, glm::vec3(-0.5f), glm::vec3(0.5f));
        out.push_back(t);
    }
    return out;
}

/// A flat quad as two triangles.
inline void addQuad(std::vector<Triangle>& out, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
    out.push_back({{a, b, c}, 0});
    out.push_back({{a, c, d}, 0});
}

/// Receivers at @p points, facing +y.
inline ReceiverSet receiversFacingUp(const std::vector<glm::vec3>& points) {
    ReceiverSet set;
    set.position = points;
    set.normal.assign(points.size(), glm::vec3(0, 1, 0));
    return set;
}

/// Random receivers in a box with random unit normals.
inline ReceiverSet randomReceivers(uint64_t seed, int count, glm::vec3 lo, glm::vec3 hi) {
    Rng rng(seed);
    ReceiverSet set;
    for (int i = 0; i < count; ++i) {
        set.position.push_back(randomIn(rng, lo, hi));
        set.normal.push_back(glm::normalize(randomIn(rng, glm::vec3(-1), glm::vec3(1)) + glm::vec3(0, 1e-3f, 0)));
    }
    return set;
}

/// Receivers on the given triangles (barycentric points, some very close to edges).
inline void addReceiversOnTriangles(ReceiverSet& set, const std::vector<Triangle>& tris, uint64_t seed, int perTriangle) {
    Rng rng(seed);
    for (const Triangle& t : tris)
        for (int i = 0; i < perTriangle; ++i) {
            double a = rng.uniform(), b = rng.uniform();
            if (a + b > 1) a = 1 - a, b = 1 - b;
            if (i % 3 == 0) b = rng.uniform() * 1e-6;  // hugging an edge
            glm::dvec3 p = glm::dvec3(t.v[0]) + a * glm::dvec3(t.v[1] - t.v[0]) + b * glm::dvec3(t.v[2] - t.v[0]);
            set.position.push_back(glm::vec3(p));
            set.normal.push_back(glm::normalize(glm::cross(t.v[1] - t.v[0], t.v[2] - t.v[0])));
        }
}

inline std::vector<uint32_t> assignSets(const ReceiverSet& r, int sets, uint64_t seed = 1) {
    std::vector<uint32_t> out(r.size());
    for (size_t i = 0; i < out.size(); ++i) out[i] = uint32_t(sampleSetOf(i, sets, seed));
    return out;
}

inline LightDesc rectLight(glm::dvec3 center, glm::dvec3 u, glm::dvec3 v, int samples = 64, int sets = 4) {
    LightDesc l;
    l.type = LightType::Rect, l.center = center, l.u = u, l.v = v, l.samples = samples, l.sampleSets = sets;
    return l;
}

/// A square floor of side 2 @p half at height @p y, as two triangles.
inline std::vector<Triangle> floorQuad(float half, float y = 0.f) {
    std::vector<Triangle> t;
    addQuad(t, {-half, y, -half}, {half, y, -half}, {half, y, half}, {-half, y, half});
    return t;
}

/// spot.obj (watertight, wound outward) standing one unit above the origin.
inline std::vector<Triangle> spotMesh() {
    Transform place;
    place.translate = {0, 1.0f, 0};
    TransformedSource spot(openObj(sharedData("meshes/spot.obj")), place.matrix());
    std::vector<Triangle> mesh = readAll(spot);
    REQUIRE(mesh.size() == 5856);
    return mesh;
}

inline std::vector<Triangle> everyNth(const std::vector<Triangle>& tris, size_t n) {
    std::vector<Triangle> some;
    for (size_t i = 0; i < tris.size(); i += n) some.push_back(tris[i]);
    return some;
}

inline LightDesc sunLight(glm::dvec3 direction, double diameterDeg, int samples, int sets = 4) {
    LightDesc l;
    l.type = LightType::Sun, l.direction = direction, l.angularDiameterDeg = diameterDeg;
    l.samples = samples, l.sampleSets = sets, l.where = "sun";
    return l;
}

/// A patch of grass blades on a floor, receivers on the floor and on the blades.
inline void grassScene(std::vector<Triangle>& tris, ReceiverSet& receivers, int blades) {
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

/// Three boxes (closed solids) on a floor, receivers on the floor and on the boxes.
inline void boxesScene(std::vector<Triangle>& tris, ReceiverSet& receivers) {
    std::vector<BoxShape> boxes = {{{-1, 0, -1}, {-0.4, 0.8, -0.2}}, {{0.2, 0, 0.1}, {0.9, 0.4, 0.7}},
                                   {{-0.3, 0.9, 0.2}, {0.1, 1.1, 0.6}}};
    tris = readAll(*makeBoxSource(boxes));
    std::vector<Triangle> floor;
    addQuad(floor, {-3, 0, -3}, {3, 0, -3}, {3, 0, 3}, {-3, 0, 3});
    addReceiversOnTriangles(receivers, floor, 41, 700);
    addReceiversOnTriangles(receivers, tris, 42, 8);
    tris.insert(tris.end(), floor.begin(), floor.end());
}

/// The disk, sphere and tilted polygon lights of the light-type tests (all above y = 4).
inline LightDesc diskLight() {
    LightDesc disk;
    disk.type = LightType::Disk, disk.center = {0.5, 4.5, -0.3}, disk.normal = {0.2, -1, 0.1}, disk.radius = 0.9;
    disk.samples = 100, disk.sampleSets = 3;
    return disk;
}

inline LightDesc sphereLight() {
    LightDesc sphere;
    sphere.type = LightType::Sphere, sphere.center = {-0.5, 4.2, 0.4}, sphere.radius = 0.6, sphere.samples = 96;
    sphere.sampleSets = 4;
    return sphere;
}

inline LightDesc polygonLight() {
    LightDesc polygon;
    polygon.type = LightType::Polygon;
    for (glm::dvec2 q : {glm::dvec2(-1, -1), {1, -1}, {1.4, 0.5}, {0, 1.2}, {-1.2, 0.3}})  // tilted plane
        polygon.polygon.push_back({q.x, 4.2 + 0.15 * q.x + 0.1 * q.y, q.y});
    polygon.samples = 80, polygon.sampleSets = 2;
    return polygon;
}

/// Blockers and receivers for the light-type tests: a triangle soup over a floor, receivers on
/// the floor and on the blockers; the floor is appended to @p tris.
inline void soupOverFloor(std::vector<Triangle>& tris, ReceiverSet& receivers) {
    tris = triangleSoup(5, 50, {-2, 1, -2}, {2, 2.5f, 2}, 1.0f);
    std::vector<Triangle> floor;
    addQuad(floor, {-4, 0, -4}, {4, 0, -4}, {4, 0, 4}, {-4, 0, 4});
    addReceiversOnTriangles(receivers, floor, 6, 250);
    addReceiversOnTriangles(receivers, tris, 7, 2);
    tris.insert(tris.end(), floor.begin(), floor.end());
}

/// Runs hierarchical penumbra casting and converts the result to VisibilityMasks; the cast's
/// counters go to @p stats when given.
inline VisibilityMasks castHpc(const LightSamples& samples, const ReceiverSet& receivers,
                               const std::vector<uint32_t>& sets, std::vector<Triangle> triangles,
                               const CastOptions& options, int tiles = 1, size_t chunk = 97,
                               CastStats* stats = nullptr) {
    if (options.sortBlockers) sortByAreaDescending(triangles);
    PenumbraCaster caster(samples, receivers, sets, options, tiles);
    for (size_t i = 0; i < triangles.size(); i += chunk)
        caster.cast(std::span<const Triangle>(triangles.data() + i, std::min(chunk, triangles.size() - i)));
    VisibilityMasks masks(receivers.size(), samples.groupCount());
    caster.finish([&](uint32_t r, const uint64_t* words, bool full) {
        for (int k = 0; k < masks.groups; ++k)
            masks.row(r)[k] = full ? samples.groups[k].fullMask() : (words ? words[k] : 0);
    });
    if (stats) *stats = caster.stats();
    return masks;
}

/// Every combination worth testing: all on, each optimization off alone, all off.
inline std::vector<std::pair<std::string, CastOptions>> optionVariants() {
    std::vector<std::pair<std::string, CastOptions>> v;
    CastOptions base;
    base.rebuildThreshold = 0.05;  // rebuild often so rebuilds are exercised
    base.hierarchy.leafSize = 4;
    base.hierarchy.medianSplitAbove = 64;
    v.push_back({"all on", base});
    auto off = [&](const char* name, auto change) {
        CastOptions o = base;
        change(o);
        v.push_back({name, o});
    };
    off("no umbra bits (A)", [](CastOptions& o) { o.umbraBits = false; });
    off("no active planes (B)", [](CastOptions& o) { o.activePlanes = false; });
    off("no lazy volumes (C)", [](CastOptions& o) { o.lazyVolumes = false; });
    off("no lazy masks (D)", [](CastOptions& o) { o.lazyMasks = false; });
    off("no rebuild", [](CastOptions& o) { o.rebuild = false; });
    // The default is the best SIMD level of the CPU; the others must give the same bits.
    off("scalar kernels", [](CastOptions& o) { o.simd = SimdLevel::Scalar; });
    off("sse2 kernels", [](CastOptions& o) { o.simd = SimdLevel::Sse2; });
    off("no sample table", [](CastOptions& o) { o.sampleTable = false; });
    off("no closed casters", [](CastOptions& o) { o.closedCasters = false; });
    off("group volumes for the first receiver", [](CastOptions& o) { o.groupVolumesAfter = 0; });
    off("group volumes after three receivers", [](CastOptions& o) { o.groupVolumesAfter = 3; });
    off("no footprints", [](CastOptions& o) { o.footprints = false; });
    off("no alpha bounds", [](CastOptions& o) { o.alphaBounds = false; });
    off("no front plane", [](CastOptions& o) { o.frontPlane = false; });
    off("all off", [](CastOptions& o) {
        o.umbraBits = o.activePlanes = o.lazyVolumes = o.lazyMasks = o.rebuild = o.sortBlockers = o.sampleTable =
            o.closedCasters = o.footprints = o.alphaBounds = o.frontPlane = false, o.groupVolumesAfter = 0;
    });
    return v;
}

/// Hierarchical penumbra casting with every optimization variant and tile counts 1 and 3 must
/// give masks bit-identical to the reference ray caster. The scene must have both blocked and
/// unblocked relations: one where nothing (or everything) is blocked proves little.
inline void requireMatchesReference(const std::string& scene, const std::vector<LightDesc>& lights,
                                    const ReceiverSet& receivers, const std::vector<Triangle>& triangles, int groupSize = 64) {
    LightSamples samples = generateLightSamples(lights, groupSize, 7);
    std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    VisibilityMasks reference = castReference(samples, receivers, sets, triangles, receiverEpsilonOf(CastOptions()));
    INFO(scene << ": " << reference.blockedCount() << " blocked of " << receivers.size() * samples.sampleCount);
    REQUIRE(reference.blockedCount() > 0);
    REQUIRE(reference.blockedCount() < uint64_t(receivers.size()) * samples.sampleCount);
    for (const auto& [name, options] : optionVariants()) {
        for (int tiles : {1, 3}) {
            INFO(name << ", tiles " << tiles);
            VisibilityMasks hpc = castHpc(samples, receivers, sets, triangles, options, tiles);
            CHECK(hpc.blockedCount() == reference.blockedCount());
            CHECK(hpc.words == reference.words);
        }
    }
}

}  // namespace penumbra::test
