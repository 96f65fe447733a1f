#pragma once
/// @file EmbreeCaster.h
/// @brief `--method embree`: the ray-tracing peer. Intel Embree 3 traces one shadow ray per
/// receiver-sample relation with rtcOccluded16 packets, over exactly the receivers and samples
/// the other methods use. Embree decides in float with its own edge rules, so it may differ from
/// the blocking rule on ties only; `penumbra compare --scene` counts those. The ties (all within
/// isTie()'s tolerance, details in EmbreeCaster.cpp):
///  - float ray and hit distance versus the rule's double evaluation;
///  - rays through a triangle edge or vertex (Embree's float test is not exactly edge-inclusive);
///  - receivers within eps(r) of a triangle's plane: the rule measures eps(r) perpendicular to the
///    plane, Embree along the ray (tnear), so grazing rays may be blocked by Embree only;
///  - samples within 1e-6 |l - r| of a triangle's plane (the ray ends at tfar = 1 - 1e-6).
/// The BVH is built with RTC_BUILD_QUALITY_HIGH: one build, many rays per triangle.

#include "bake/Light.h"
#include "bake/VisibilityMasks.h"
#include "receivers/ReceiverSet.h"
#include "stream/Triangle.h"

#include <functional>
#include <span>

namespace penumbra {

/// @brief Timings of an Embree cast, reported by the stats and the benchmark.
struct EmbreeStats {
    double buildSeconds = 0;  ///< device + scene + BVH build
    double traceSeconds = 0;
    uint64_t rays = 0;
    uint64_t sceneBytes = 0;  ///< vertex and index buffers handed to Embree (its BVH comes on top)
};

/// @brief Casts every relation. The ray of receiver r and sample l starts at r with
/// tnear = eps(r) (the receiver-end epsilon, BlockingRule.h) and ends at l (tfar just below 1
/// in units of l - r, so the light sample itself is never hit).
/// @param progress optional, called with the number of receivers finished.
/// @throw InputError when Embree reports an error (the message carries Embree's error code).
VisibilityMasks castEmbree(const LightSamples& samples, const ReceiverSet& receivers,
                           std::span<const uint32_t> sampleSetOf, std::span<const Triangle> triangles,
                           double epsilon, EmbreeStats* stats = nullptr,
                           const std::function<void(uint64_t)>& progress = {});

}  // namespace penumbra
