#include "bake/cast/ClosedExemptions.h"

#include "bake/cast/BlockerBatch.h"
#include "bake/cast/HardShadowBlock.h"
#include "stream/Translucency.h"
#include "stream/util/StopRequest.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

/// The smallest largestCoordinate() of any point in the box [@p lo, @p hi].
double smallestCoordinate(const glm::vec3& lo, const glm::vec3& hi) {
    double least = 0.0;
    for (int i = 0; i < 3; ++i) least = std::max(least, lo[i] > 0.0f ? double(lo[i]) : hi[i] < 0.0f ? -double(hi[i]) : 0.0);
    return least;
}

/// n . p - c, in the order the box bounds below use: each term of a point inside a box is at most
/// (at least) that of the box's far (near) corner, and rounding is monotone, so a box culled by
/// its bound holds no point that passes.
double planeValue(const glm::dvec3& n, double c, const glm::dvec3& p) { return n.x * p.x + n.y * p.y + n.z * p.z - c; }

/// Inside G's prism by more than @p margin: the projection of @p r on G's plane is that far
/// inside every edge. cross(n, b - a) points into the triangle for the winding that gives n.
bool deepInsidePrism(const BlockerTriangle& g, const glm::dvec3& r, double margin) {
    for (int e = 0; e < 3; ++e) {
        const glm::dvec3& a = g.v[e];
        const glm::dvec3 inward = glm::cross(g.plane.n, g.v[(e + 1) % 3] - a);
        const double length = glm::length(inward);
        if (!(glm::dot(inward, r - a) > margin * length)) return false;
    }
    return true;
}


/// Whether the segment from @p r (behind G) to one of @p samples crosses G, its edge planes taken
/// with a relative 1e-9 of slack: the rule's own test without its epsilon, and wider.
bool segmentLeavesThrough(const BlockerTriangle& g, const glm::dvec3& r, std::span<const glm::vec3> samples, double w) {
    for (const glm::vec3& sample : samples) {
        // r is behind G (d < 0): only a sample in front of it can be reached through G.
        if (!(g.side(glm::dvec3(sample), w) > 0.0)) continue;
        const HardShadowVolume h = makeHardShadowVolume(glm::dvec3(sample), w, g);
        bool inside = true;
        for (int e = 0; e < 3 && inside; ++e) {
            const glm::dvec3 at = r - g.v[e];
            inside = edgeValue(h, g, e, r) >= -1e-9 * glm::length(h.edge[e]) * glm::length(at);
        }
        if (inside) return true;
    }
    return false;
}

}  // namespace

bool closedFaceMayFailAt(const BlockerTriangle& g, const PenumbraVolume& volume, const glm::dvec3& r,
                         const ReceiverEpsilon& epsilon, std::span<const glm::vec3> samples, double w) {
    const double margin = closedExemptionMargin(largestCoordinate(r), largestCoordinate(g.v[0]));
    const double band = epsilon.at(r) + margin;
    const double d = planeValue(g.plane.n, glm::dot(g.plane.n, g.v[0]), r);
    if (!(d >= -band && d < -closedOnPlaneBand(largestCoordinate(r), largestCoordinate(g.v[0])))) return false;
    if (!contains(volume, r, volume.all())) return false;
    if (deepInsidePrism(g, r, margin)) return false;
    return segmentLeavesThrough(g, r, samples, w);
}

/// A bounding-volume hierarchy over receiver ids: median splits on the longest axis, 16 per leaf.
struct ClosedExemptionFinder::Index {
    struct Node {
        glm::vec3 lo, hi;
        uint32_t begin, end;
        uint32_t left = 0, right = 0;  ///< children; 0: a leaf
    };
    static constexpr uint32_t kLeaf = 16;
    std::vector<uint32_t> ids;
    std::vector<Node> nodes;

    Index(const ReceiverSet& receivers, std::span<const uint32_t> from) : ids(from.begin(), from.end()) {
        if (ids.empty()) return;
        nodes.reserve(2 * (ids.size() / kLeaf + 1));
        build(receivers, 0, uint32_t(ids.size()));
    }

    uint32_t build(const ReceiverSet& receivers, uint32_t begin, uint32_t end) {
        const uint32_t at = uint32_t(nodes.size());
        nodes.push_back({glm::vec3(INFINITY), glm::vec3(-INFINITY), begin, end});
        glm::vec3 lo(INFINITY), hi(-INFINITY);
        for (uint32_t i = begin; i < end; ++i) lo = glm::min(lo, receivers.position[ids[i]]), hi = glm::max(hi, receivers.position[ids[i]]);
        nodes[at].lo = lo, nodes[at].hi = hi;
        if (end - begin <= kLeaf) return at;
        const glm::vec3 size = hi - lo;
        const int axis = size.x >= size.y && size.x >= size.z ? 0 : size.y >= size.z ? 1 : 2;
        const uint32_t mid = begin + (end - begin) / 2;
        // Ties broken by id, so that the tree depends only on the set of ids.
        std::nth_element(ids.begin() + begin, ids.begin() + mid, ids.begin() + end, [&](uint32_t a, uint32_t b) {
            const float pa = receivers.position[a][axis], pb = receivers.position[b][axis];
            return pa < pb || (pa == pb && a < b);
        });
        const uint32_t left = build(receivers, begin, mid);
        const uint32_t right = build(receivers, mid, end);
        nodes[at].left = left, nodes[at].right = right;
        return at;
    }
};

ClosedExemptionFinder::ClosedExemptionFinder(const LightSamples& samples, const ReceiverSet& receivers,
                                             std::span<const uint32_t> sampleSets, std::span<const uint32_t> ids,
                                             const CastOptions& options)
    : samples_(samples), receivers_(receivers), sampleSets_(sampleSets), epsilon_(receiverEpsilonOf(options)),
      level_(hardShadowKernels(options.simd).level), index_(std::make_unique<Index>(receivers, ids)),
      marked_(std::make_unique<std::atomic<uint8_t>[]>(ids.size())) {
    for (size_t i = 0; i < ids.size(); ++i) marked_[i].store(0, std::memory_order_relaxed);
    if (!index_->nodes.empty()) root_ = {index_->nodes[0].lo, index_->nodes[0].hi};
    for (size_t l = 0; l < size_t(samples.lightCount()); ++l) {
        const uint32_t g0 = samples.lightFirstGroup[l], g1 = samples.lightFirstGroup[l + 1];
        const uint32_t first = g0 < g1 ? samples.groups[g0].first : 0;
        const uint32_t end = g0 < g1 ? samples.groups[g1 - 1].first + samples.groups[g1 - 1].count : 0;
        lightSamples_.push_back({first, end - first});
    }
}

std::span<const glm::vec3> ClosedExemptionFinder::samplesOf(uint32_t receiver, size_t l) const {
    const size_t set = sampleSets_[receiver];
    return std::span<const glm::vec3>(samples_.positions).subspan(set * size_t(samples_.sampleCount) + lightSamples_[l].first,
                                                                   lightSamples_[l].second);
}

ClosedExemptionFinder::~ClosedExemptionFinder() = default;

void ClosedExemptionFinder::scan(std::span<const Triangle> blockers) {
    if (index_->nodes.empty()) return;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, blockers.size(), 64), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i)
            if ((blockers[i].flags & kTriangleClosed) && blocksWhole(blockers[i].flags)) scanFace(blockers[i]);
    });
}

void ClosedExemptionFinder::scanFace(const Triangle& t) {
    const BlockerTriangle g = BlockerTriangle::from(t);
    if (!g.valid) return;
    const Index& index = *index_;
    const glm::dvec3& n = g.plane.n;
    const double c = glm::dot(n, g.v[0]), vertex = largestCoordinate(g.v[0]);
    PenumbraVolume volume;
    thread_local std::vector<std::pair<uint32_t, uint32_t>> stack;  // node, active planes
    bool tested = false;
    for (size_t l = 0; l < samples_.lightBounds.size(); ++l) {
        const ConvexBound& bound = samples_.lightBounds[l];
        if (facesAway(g, bound)) continue;  // skipped for this light, never the face that fails
        tested = true;
        if (!buildPenumbraVolume(bound, g, volume, &root_, level_)) continue;  // V_L misses every receiver
        stack.assign(1, {0u, volume.all()});
        while (!stack.empty()) {
            auto [at, active] = stack.back();
            stack.pop_back();
            const Index::Node& node = index.nodes[at];
            const double extent = largestCoordinate(Box{node.lo, node.hi});
            const double margin = closedExemptionMargin(extent, vertex);
            const double band = epsilon_.at(glm::dvec3(extent)) + margin;
            const double far = std::max(n.x * node.lo.x, n.x * node.hi.x) + std::max(n.y * node.lo.y, n.y * node.hi.y) +
                               std::max(n.z * node.lo.z, n.z * node.hi.z) - c;
            const double near = std::min(n.x * node.lo.x, n.x * node.hi.x) + std::min(n.y * node.lo.y, n.y * node.hi.y) +
                                std::min(n.z * node.lo.z, n.z * node.hi.z) - c;
            // The slab behind G's plane misses the box; the on-plane band taken at the box's point
            // nearest the origin, where it is narrowest.
            if (far < -band || near >= -closedOnPlaneBand(smallestCoordinate(node.lo, node.hi), vertex)) continue;
            const Box box{node.lo, node.hi};
            if (!(level_ == SimdLevel::Avx2 ? intersectsAvx2(volume, box, active) : intersects(volume, box, active))) continue;
            if (node.left) {
                stack.push_back({node.left, active}), stack.push_back({node.right, active});
                continue;
            }
            for (uint32_t i = node.begin; i < node.end; ++i) {
                if (marked_[i].load(std::memory_order_relaxed)) continue;
                const uint32_t id = index.ids[i];
                if (closedFaceMayFailAt(g, volume, glm::dvec3(receivers_.position[id]), epsilon_, samplesOf(id, l), bound.w))
                    marked_[i].store(1, std::memory_order_relaxed);
            }
        }
    }
    if (tested) facesTested_.fetch_add(1, std::memory_order_relaxed);
}

std::vector<uint32_t> ClosedExemptionFinder::exempt() const {
    std::vector<uint32_t> out;
    for (size_t i = 0; i < index_->ids.size(); ++i)
        if (marked_[i].load(std::memory_order_relaxed)) out.push_back(index_->ids[i]);
    std::sort(out.begin(), out.end());
    return out;
}

std::vector<uint32_t> findClosedExemptions(TriangleSource& blockers, const LightSamples& samples,
                                           const ReceiverSet& receivers, std::span<const uint32_t> sampleSets,
                                           std::span<const uint32_t> ids, const CastOptions& options,
                                           uint64_t* facesTested) {
    ClosedExemptionFinder finder(samples, receivers, sampleSets, ids, options);
    std::vector<Triangle> chunk(kTriangleChunk);
    while (size_t n = blockers.read(chunk)) {
        finder.scan(std::span<const Triangle>(chunk.data(), n));
        throwIfStopRequested("cast");
    }
    if (facesTested) *facesTested = finder.facesTested();
    return finder.exempt();
}

}  // namespace penumbra
