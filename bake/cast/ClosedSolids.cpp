#include "bake/cast/ClosedSolids.h"

#include "stream/util/Memory.h"
#include "stream/Translucency.h"

#include <glm/common.hpp>

#include <algorithm>
#include <cmath>

namespace penumbra {

ClosedSolidScan::ClosedSolidScan(const LightSamples& samples) : result_{{}, 0, std::vector<uint64_t>(samples.lightCount(), 0), {}} {
    for (const ConvexBound& bound : samples.lightBounds) {
        Aabb box{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
        if (!bound.directional())
            for (const glm::dvec3& v : bound.vertices) {
                // Grown by a relative margin: the bound holds the float samples up to roundoff.
                const double m = 1e-6 * std::max({1.0, std::abs(v.x), std::abs(v.y), std::abs(v.z)});
                box.lo = glm::min(box.lo, roundToFloat(v - m, true));
                box.hi = glm::max(box.hi, roundToFloat(v + m, false));
            }
        lights_.push_back(box);
    }
}

void ClosedSolidScan::closeSolid() {
    if (current_ == SolidSegmenter::kNone) return;
    bool opened = false;
    for (size_t l = 0; l < lights_.size(); ++l) {
        const Aabb& a = lights_[l];
        const bool meets = a.lo.x <= box_.hi.x && a.hi.x >= box_.lo.x && a.lo.y <= box_.hi.y && a.hi.y >= box_.lo.y &&
                           a.lo.z <= box_.hi.z && a.hi.z >= box_.lo.z;
        if (meets) ++result_.perLight[l], opened = true;
    }
    // With the triangles held, every part is checked, not only those contiguous in the stream.
    const SolidParts parts = tooMany_ ? SolidParts{} : solidParts(triangles_);
    const bool balanced = edges_.balanced(), outward = balanced && volume_.outward() && !currentRunInward_ && !parts.inward;
    // Crossings are looked for only in a solid that passed the cheaper checks (and is not opened
    // for a light already: it is cast as open either way).
    const bool crossing = outward && !opened && !tooMany_ && (parts.sharedEdge || solidMayCrossItself(triangles_));
    if (!outward || crossing || (!opened && tooMany_)) {
        if (result_.leaky.empty() || result_.leaky.back().part != currentPart_) result_.leaky.push_back({currentPart_});
        OpenedSolids::Leaky& leaky = result_.leaky.back();
        ++(!balanced ? leaky.solids : !outward ? leaky.inward : crossing ? leaky.crossing : leaky.unchecked);
        leaky.triangles += currentTriangles_;
        opened = true;
    }
    opened = opened || (currentOpaque_ && currentSeeThrough_);
    if (opened) result_.ordinals.push_back(current_), result_.triangles += currentTriangles_;
    else ++result_.kept, result_.smallestExtent = std::min({result_.smallestExtent, box_.hi.x - box_.lo.x, box_.hi.y - box_.lo.y, box_.hi.z - box_.lo.z});
    current_ = SolidSegmenter::kNone;
}

void ClosedSolidScan::scan(std::span<const Triangle> chunk, uint32_t part) {
    for (const Triangle& t : chunk) {
        const uint64_t solid = segmenter_.next(t);
        if (solid != current_) {
            closeSolid();
            current_ = solid;
            currentTriangles_ = 0, currentPart_ = part;
            box_ = {glm::vec3(INFINITY), glm::vec3(-INFINITY)};
            edges_.reset(), volume_.reset(), runVolume_.reset();
            currentOpaque_ = currentSeeThrough_ = currentRunInward_ = tooMany_ = false;
            triangles_.clear();
        }
        if (solid == SolidSegmenter::kNone) continue;
        ++currentTriangles_;
        const bool opaque = blocksWhole(t.flags);
        currentOpaque_ = currentOpaque_ || opaque, currentSeeThrough_ = currentSeeThrough_ || !opaque;
        edges_.add(t), volume_.add(t), runVolume_.add(t);
        // A run of the solid's triangles whose edges balance is a closed surface of its own (the
        // solid's parts are usually contiguous: an OBJ's objects, a glTF's primitives): each
        // must be wound outward, or a part wound inward hides behind a larger one.
        if (edges_.balanced()) currentRunInward_ = currentRunInward_ || !runVolume_.outward(), runVolume_.reset();
        for (const glm::vec3& v : t.v) box_.lo = glm::min(box_.lo, v), box_.hi = glm::max(box_.hi, v);
        if (tooMany_) continue;
        if (triangles_.size() < kMaxCheckedSolidTriangles) triangles_.push_back({{t.v[0], t.v[1], t.v[2]}});
        else tooMany_ = true, releaseStorage(triangles_);  // given back: the solid is opened unchecked
    }
}

OpenedSolids ClosedSolidScan::finish() {
    closeSolid();
    return result_;  // ordinals were appended in stream order: sorted
}

size_t OpenSolidsSource::read(std::span<Triangle> out) {
    const size_t n = inner_->read(out);
    if (opened_.empty()) return n;
    for (size_t i = 0; i < n; ++i) {
        const uint64_t solid = segmenter_.next(out[i]);
        if (solid == SolidSegmenter::kNone) continue;
        while (nextOpened_ < opened_.size() && opened_[nextOpened_] < solid) ++nextOpened_;
        if (nextOpened_ < opened_.size() && opened_[nextOpened_] == solid)
            out[i].flags &= ~(kTriangleClosed | kTriangleSolidStart);
    }
    return n;
}

}  // namespace penumbra
