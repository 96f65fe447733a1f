#pragma once
/// @file EmbreeCaster.h
/// @brief `--method embree`: the ray-tracing peer. Intel Embree 3 traces one shadow ray per
/// receiver-sample relation with rtcOccluded16 packets, over exactly the receivers and samples
/// the other methods use: a ray towards each point sample, and a ray to infinity along each sun
/// direction. Embree finds the candidate triangles in float; an occlusion filter function then
/// accepts a hit only when the one blocking rule (BlockingRule.h) blocks the relation with that
/// triangle, so the receiver epsilon and the open light end mean the same as for hpc. Embree can
/// then differ from the rule on one kind of tie only: a segment within float roundoff of a
/// triangle's edge, which Embree's float test may miss (bake/TieClassifier.h classifies them).
/// The BVH is built with RTC_BUILD_QUALITY_HIGH: one build, many rays per triangle.

#include "bake/rule/BlockingRule.h"
#include "bake/light/Light.h"
#include "bake/cast/VisibilityMasks.h"
#include "receivers/ReceiverSet.h"
#include "stream/AlphaTable.h"
#include "stream/Triangle.h"

#include <functional>
#include <memory>
#include <vector>
#include <span>

namespace penumbra {

/// @brief Timings of an Embree cast, reported by the stats and the benchmark.
struct EmbreeStats {
    double buildSeconds = 0;  ///< device + scene + BVH build
    double traceSeconds = 0;
    uint64_t rays = 0;
    uint64_t filterCalls = 0;  ///< candidate hits the blocking-rule filter judged
    uint64_t filterExact = 0;  ///< of those, hits not certain from Embree's own hit: the rule decided
    uint64_t filterRejected = 0;  ///< of those, hits the rule does not count (epsilon band, edges)
    uint64_t sceneBytes = 0;  ///< vertex and index buffers handed to Embree, and the filter's alpha id and longest edge per triangle (its BVH comes on top)
};

/// @brief Casts every relation. The ray of receiver r and sample l starts at r with
/// tnear = eps(r) / 2 (no triangle nearer along the ray can pass the rule's epsilon band) and ends
/// just beyond l (tfar = 1 + 1e-5 in units of l - r; the filter rejects what lies beyond l), or at
/// infinity for a direction.
/// With @p ruleFilter false, no filter is installed: Embree's native answer, the ray from
/// tnear = eps(r) along it to just before the sample (tfar = 1 - 1e-6), which may also block
/// grazing rays within eps(r) of a plane that the rule does not; faster, for benchmarks.
/// Hits on alpha triangles (alphaIdOf() != 0) always go through the filter, which applies the
/// rule and the alpha test of @p alpha (AlphaRule.h; null: the built-in outlines), so Embree
/// looks further along the ray past a transparent texel, with or without @p ruleFilter.
/// Translucent triangles (stream/Translucency.h) go into the BVH only when @p depths is given:
/// the filter then runs the rule on every hit on one, adds its optical depth to the ray's once
/// per primitive (Embree may report a primitive more than once) and rejects the hit, so the ray
/// goes on; an opaque hit ends the ray as before. Without @p depths they block nothing.
/// @param progress optional, called with the number of receivers finished.
/// @param depths when given: per receiver, its samples' R, G, B depths (sampleCount x 3), or
///        null where no unblocked sample crossed a translucent triangle (allocated lazily).
/// @throw InputError when Embree reports an error (the message carries Embree's error code).
VisibilityMasks castEmbree(const LightSamples& samples, const ReceiverSet& receivers,
                           std::span<const uint32_t> sampleSetOf, std::span<const Triangle> triangles,
                           const ReceiverEpsilon& epsilon, EmbreeStats* stats = nullptr,
                           const std::function<void(uint64_t)>& progress = {}, bool ruleFilter = true,
                           const AlphaTable* alpha = nullptr, std::vector<std::unique_ptr<uint32_t[]>>* depths = nullptr);

}  // namespace penumbra
