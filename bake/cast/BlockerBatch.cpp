#include "bake/cast/BlockerBatch.h"

#include "stream/Translucency.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace penumbra {

bool facesAway(const BlockerTriangle& t, const ConvexBound& bound) {
    const glm::dvec3& v0 = t.v[0];
    for (const glm::dvec3& v : bound.vertices) {
        const glm::dvec3 d = v - bound.w * v0;
        const double m = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
        if (!(glm::dot(t.plane.n, d) < -1e-9 * m)) return false;
    }
    return !bound.vertices.empty();
}

bool cutInFront(PenumbraVolume& volume, const BlockerTriangle& t, const Box& receivers, double receiversExtent,
                const CastOptions& options) {
    if (volume.count >= PenumbraVolume::kMaxPlanes) return true;
    // inFrontOfClosed() culls a box at closedFrontMargin(extent(box), |c - v0|_1), c its corner
    // nearest T's front. Over the boxes inside `receivers` the extent is at most E, the largest
    // |coordinate| of a receiver, and |c - v0|_1 at most 3 (E + V), V that of v0; one more (E + V)
    // covers the rounding of this plane's evaluation (about 1e-15 (E + V)) against
    // distanceBehind()'s.
    const double e = receiversExtent;
    const double v = std::max({std::abs(t.v[0].x), std::abs(t.v[0].y), std::abs(t.v[0].z)});
    const double margin = closedFrontMargin(options, e, 4 * (e + v));
    const Plane behind{-t.plane.n, glm::dot(t.plane.n, t.v[0]) + margin};  // positive side: inside
    if (classify(behind, receivers) == BoxSide::Outside) return false;
    volume.push(behind);
    volume.frontCulled = true;
    return true;
}

BlockerCulls::BlockerCulls(const LightSamples& samples, const CastOptions& options, const Box& receivers)
    : samples_(samples), options_(options), receivers_(receivers), receiversExtent_(largestCoordinate(receivers)), volumeLevel_(hardShadowKernels(options.simd).level) {
    for (const ConvexBound& bound : samples_.lightBounds) reach_.emplace_back(receivers_, bound);
}

uint64_t BlockerCulls::prepare(BlockerBatch& batch, std::span<const Triangle> blockers) const {
    const size_t n = blockers.size(), lights = size_t(samples_.lightCount());
    batch.n = n;
    if (batch.prepared.size() < n) {
        batch.prepared.resize(n);
        batch.lightVolumes.resize(n * lights);
        batch.lightActive.resize(n * lights);
    }
    std::atomic<uint64_t> closedBackFaces{0};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 256), [&](const tbb::blocked_range<size_t>& range) {
        uint64_t backFaces = 0;
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const Triangle& tri = blockers[i];
            const Box box{glm::min(glm::min(tri.v[0], tri.v[1]), tri.v[2]), glm::max(glm::max(tri.v[0], tri.v[1]), tri.v[2])};
            uint8_t* active = &batch.lightActive[i * lights];
            // Switches off the lights for which @p drop(l) holds; false when none is left.
            auto keepLights = [&](auto&& drop) {
                bool any = false;
                for (size_t l = 0; l < lights; ++l) {
                    if (active[l] && drop(l)) active[l] = 0;
                    any = any || active[l];
                }
                return any;
            };
            BlockerTriangle& prepared = batch.prepared[i];
            prepared.valid = false;
            for (size_t l = 0; l < lights; ++l) active[l] = 1;
            if (!blocksAsOpaque(tri.flags)) continue;  // "cast_shadows": false, or translucent
            if (!keepLights([&](size_t l) { return !reach_[l].boxMeets(box); })) continue;  // out of every reach box
            // Beside the light: T's ball misses the hull of the light's and the receivers' balls.
            const glm::dvec3 v[3] = {glm::dvec3(tri.v[0]), glm::dvec3(tri.v[1]), glm::dvec3(tri.v[2])};
            const Ball ball = boundingBall(v);
            if (!keepLights([&](size_t l) { return reach_[l].hull.misses(ball); })) continue;
            prepared = BlockerTriangle::from(tri);
            if (!prepared.valid) continue;
            // A closed surface's triangle with every light vertex strictly behind it: a segment
            // through it enters the solid, and the triangle where it leaves faces the light.
            // A closed surface with cut-outs is not closed: its far side may not block.
            if (options_.closedCasters && (tri.flags & kTriangleClosed) && !prepared.alpha &&
                !keepLights([&](size_t l) { return facesAway(prepared, samples_.lightBounds[l]); })) {
                prepared.valid = false;
                ++backFaces;
                continue;
            }
            prepared.closed = options_.closedCasters && (tri.flags & kTriangleClosed) && !prepared.alpha;
            // V_L is built plane by plane and abandoned as soon as one plane leaves every receiver
            // outside (first the cap: every receiver on the light's side of T's plane), so a
            // blocker culled at the root rarely pays for its whole volume.
            if (!keepLights([&](size_t l) {
                    PenumbraVolume& volume = batch.lightVolumes[i * lights + l];
                    return !buildPenumbraVolume(samples_.lightBounds[l], prepared, volume, &receivers_, volumeLevel_) ||
                           (prepared.closed && options_.frontPlane && !cutInFront(volume, prepared, receivers_, receiversExtent_, options_));
                }))
                prepared.valid = false;
        }
        closedBackFaces += backFaces;
    });
    return closedBackFaces.load();
}

}  // namespace penumbra
