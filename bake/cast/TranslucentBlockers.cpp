#include "bake/cast/TranslucentBlockers.h"

#include "bake/rule/AlphaRule.h"
#include "stream/util/Error.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <bit>
#include <stdexcept>

namespace penumbra {
namespace {

/// Distance from @p p to the segment [a, b].
double distanceToSegment(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b) {
    const glm::dvec3 ab = b - a;
    const double len2 = glm::dot(ab, ab);
    const double s = len2 > 0 ? std::clamp(glm::dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
    return glm::length(p - (a + s * ab));
}

}  // namespace

TranslucentBlockers::TranslucentBlockers(TriangleSource& blockers, const LightSamples& samples, SimdLevel simd,
                                         uint64_t cacheBytes)
    : samples_(&samples) {
    blockers.rewind();
    std::vector<Triangle> chunk(kTriangleChunk);
    while (const size_t n = blockers.read(chunk))
        for (size_t i = 0; i < n; ++i) add(chunk[i]);
    blockers.rewind();
    prepare(simd, cacheBytes);
}

TranslucentBlockers::TranslucentBlockers(std::span<const Triangle> triangles, const LightSamples& samples, SimdLevel simd,
                                         uint64_t cacheBytes)
    : samples_(&samples) {
    for (const Triangle& t : triangles) add(t);
    prepare(simd, cacheBytes);
}

void TranslucentBlockers::add(const Triangle& t) {
    const uint32_t id = alphaIdOf(t.flags);
    if (!isTranslucentId(id) || (t.flags & kTriangleNoCast)) return;
    const BlockerTriangle b = BlockerTriangle::from(t);
    if (!b.valid) return;
    Sphere s;
    s.centre = (b.v[0] + b.v[1] + b.v[2]) / 3.0;
    for (const glm::dvec3& v : b.v) s.radius = std::max(s.radius, glm::length(v - s.centre));
    tris_.push_back(b), spheres_.push_back(s), depths_.push_back(opticalDepthOf(id));
}

void TranslucentBlockers::prepare(SimdLevel simd, uint64_t cacheBytes) {
    const LightSamples& ls = *samples_;
    groups_.assign(ls.groups.size(), Sphere{});
    for (size_t k = 0; k < ls.groups.size(); ++k) {
        const LightSampleGroup& g = ls.groups[k];
        blockFirst_.push_back(uint32_t(blocksPerSet_));
        blocksPerSet_ += hardShadowBlocksFor(g.count);
        if (ls.w(g.light) == 0.0) continue;  // directions: no sphere, every sample is tested
        glm::dvec3 lo(INFINITY), hi(-INFINITY);
        for (int set = 0; set < ls.sets; ++set)
            for (uint32_t j = 0; j < g.count; ++j) {
                const glm::dvec3 p(ls.position(set, int(g.first + j)));
                lo = glm::min(lo, p), hi = glm::max(hi, p);
            }
        groups_[k].centre = 0.5 * (lo + hi);
        groups_[k].radius = 0.5 * glm::length(hi - lo);
    }
    kernels_ = hardShadowKernels(simd);
    // A volume depends on the sample and the triangle only: build the first triangles' once.
    const uint64_t perTriangle = uint64_t(ls.sets) * blocksPerSet_ * sizeof(HardShadowBlock);
    cached_ = perTriangle ? size_t(std::min<uint64_t>(tris_.size(), cacheBytes / perTriangle)) : 0;
    cache_.resize(cached_ * size_t(ls.sets) * blocksPerSet_);
    for (size_t i = 0; i < cached_; ++i)
        for (int set = 0; set < ls.sets; ++set)
            for (size_t k = 0; k < ls.groups.size(); ++k) {
                const LightSampleGroup& g = ls.groups[k];
                HardShadowBlock* blocks = &cache_[(i * size_t(ls.sets) + size_t(set)) * blocksPerSet_ + blockFirst_[k]];
                for (uint32_t lane0 = 0; lane0 < g.count; lane0 += HardShadowBlock::kLanes)
                    kernels_.build(blocks[lane0 / HardShadowBlock::kLanes], &ls.position(set, int(g.first + lane0)),
                                   int(std::min<uint32_t>(HardShadowBlock::kLanes, g.count - lane0)), ls.w(g.light), tris_[i]);
            }
}

size_t TranslucentBlockers::bytes() const { return bytesFor(tris_.size(), groups_.size()) + cache_.size() * sizeof(HardShadowBlock); }

uint64_t TranslucentBlockers::bytesFor(uint64_t triangles, size_t groups) {
    return triangles * (sizeof(BlockerTriangle) + sizeof(Sphere) + sizeof(OpticalDepth)) + groups * sizeof(Sphere);
}

const HardShadowBlock* TranslucentBlockers::blocksOf(size_t i, int set, size_t k, uint64_t open, HardShadowBlock* scratch,
                                                     uint32_t& which) const {
    which = blocksHolding(open);
    if (i < cached_) return &cache_[(i * size_t(samples_->sets) + size_t(set)) * blocksPerSet_ + blockFirst_[k]];
    const LightSampleGroup& g = samples_->groups[k];
    for (uint32_t todo = which; todo; todo &= todo - 1) {
        const int b = __builtin_ctz(todo), lane0 = b * HardShadowBlock::kLanes;
        kernels_.build(scratch[b], &samples_->position(set, int(g.first) + lane0),
                       std::min<int>(HardShadowBlock::kLanes, int(g.count) - lane0), samples_->w(g.light), tris_[i]);
    }
    return scratch;
}

bool TranslucentBlockers::depthAt(const glm::dvec3& r, int set, const uint64_t* groupWords, bool fullUmbra,
                                  const ReceiverEpsilon& epsilon, const AlphaTable&, std::span<uint32_t> depth) const {
    std::fill(depth.begin(), depth.end(), 0u);
    if (fullUmbra || tris_.empty()) return false;
    const LightSamples& ls = *samples_;
    const double eps = epsilon.at(r);
    uint64_t tested = 0, crossed = 0;
    HardShadowBlock scratch[64 / HardShadowBlock::kLanes];
    for (size_t i = 0; i < tris_.size(); ++i) {
        const BlockerTriangle& t = tris_[i];
        const double dist = distanceBehind(t, r);
        if (!(std::abs(dist) > eps)) continue;  // the rule blocks nothing within eps of the plane
        const EdgeOffsets at(t, r);
        for (size_t k = 0; k < ls.groups.size(); ++k) {
            const LightSampleGroup& g = ls.groups[k];
            const uint64_t open = ~(groupWords ? groupWords[k] : 0ull) & g.fullMask();
            if (!open) continue;
            if (ls.w(g.light) != 0.0) {  // no segment of the group comes near the triangle: a generous margin
                const double reach = groups_[k].radius + spheres_[i].radius;
                const double d = distanceToSegment(spheres_[i].centre, r, groups_[k].centre);
                if (d > reach * (1.0 + 1e-6) + 1e-9 * (glm::length(r - groups_[k].centre) + reach)) continue;
            }
            uint32_t which = 0;
            const HardShadowBlock* blocks = blocksOf(i, set, k, open, scratch, which);
            // No max_distance on translucent entries (Scene.cpp): the kernels are the whole rule.
            const uint64_t hit = kernels_.test(blocks, which, at, dist, eps) & open;
            tested += uint64_t(std::popcount(open)), crossed += uint64_t(std::popcount(hit));
            for (uint64_t bits = hit; bits; bits &= bits - 1) {
                uint32_t* d = &depth[size_t(int(g.first) + std::countr_zero(bits)) * 3];
                for (int c = 0; c < 3; ++c) d[c] = addDepth(d[c], depths_[i][c]);
            }
        }
    }
    tests.fetch_add(tested, std::memory_order_relaxed), crossings.fetch_add(crossed, std::memory_order_relaxed);
    return crossed > 0;
}

size_t OpaqueOnlySource::read(std::span<Triangle> out) {
    const size_t n = inner_.read(out);
    if (n == 0 && position_ >= collectedUpTo_) complete_ = true;
    for (size_t i = 0; i < n; ++i) {
        if (!isTranslucentId(alphaIdOf(out[i].flags))) continue;
        // Collected once, whatever the rewinds (tiles read the replay again).
        if (!complete_ && position_ + i >= collectedUpTo_ && !(out[i].flags & kTriangleNoCast)) translucent_.push_back(out[i]);
        out[i].flags |= mark_;
    }
    position_ += n;
    collectedUpTo_ = std::max(collectedUpTo_, position_);
    return n;
}

uint64_t OpaqueOnlySource::skip(uint64_t count) {
    const uint64_t n = inner_.skip(count);
    position_ += n;
    collectedUpTo_ = std::max(collectedUpTo_, position_);
    return n;
}

std::unique_ptr<TranslucentBlockers> translucentPass(const OpaqueOnlySource& view, const LightSamples& samples,
                                                     const std::string& method, const CasterTraits& traits,
                                                     const char* partialFiles, SimdLevel simd, uint64_t cacheBytes) {
    if (!view.complete()) throw std::logic_error("--method " + method + " reported a receiver before reading every blocker");
    if (view.translucent().empty()) return nullptr;
    if (partialFiles)
        fail(partialFiles, "scenes with translucent blockers cannot be sharded or checkpointed yet (their per-sample "
                           "transmittance is not in partial files)");
    // A method without masks (penumbra-map) weighs every sample's transmittance as if no opaque
    // blocker stood in the way; its visible fraction then scales the tinted irradiance.
    if (traits.translucency) return nullptr;  // Embree's filter weighs them
    return std::make_unique<TranslucentBlockers>(view.translucent(), samples, simd, cacheBytes);
}

std::vector<uint64_t> samplesOutsideSubset(const LightSamples& samples, int perLight) {
    // Farthest-point selection over the light's samples (set 0: the other sets jitter the same
    // strata): each next sample is the one farthest from those taken, so the subset covers the
    // light evenly and its samples' coordinates differ. Every k-th sample in stratum order
    // took pairs from each compact group, a few columns across the light, and a pane's edge
    // tinted in four coarse steps (0.12 of the irradiance off the exact value).
    std::vector<uint64_t> outside(size_t(samples.groupCount()), 0);
    for (int li = 0; li < samples.lightCount(); ++li) {
        const uint32_t g0 = samples.lightFirstGroup[li], g1 = samples.lightFirstGroup[li + 1];
        if (g0 == g1) continue;
        std::vector<std::pair<uint32_t, uint32_t>> at;  // (group, bit) of each sample, in order
        std::vector<glm::dvec3> position;
        for (uint32_t k = g0; k < g1; ++k) {
            outside[k] = samples.groups[k].fullMask();
            for (uint32_t j = 0; j < samples.groups[k].count; ++j)
                at.push_back({k, j}), position.push_back(glm::dvec3(samples.position(0, int(samples.groups[k].first + j))));
        }
        const size_t want = std::min(at.size(), size_t(std::max(1, perLight)));
        glm::dvec3 centre(0.0);
        for (const glm::dvec3& p : position) centre += p / double(position.size());
        std::vector<double> nearest(position.size(), INFINITY);
        size_t next = 0;  // the first: the sample nearest the centre (ties: the lower index)
        for (size_t i = 1; i < position.size(); ++i)
            if (glm::dot(position[i] - centre, position[i] - centre) < glm::dot(position[next] - centre, position[next] - centre))
                next = i;
        for (size_t taken = 0; taken < want; ++taken) {
            outside[at[next].first] &= ~(1ull << at[next].second);
            size_t farthest = next;
            double best = -1;
            for (size_t i = 0; i < position.size(); ++i) {
                nearest[i] = std::min(nearest[i], glm::dot(position[i] - position[next], position[i] - position[next]));
                if (nearest[i] > best) best = nearest[i], farthest = i;
            }
            next = farthest;
        }
    }
    return outside;
}

}  // namespace penumbra
