#pragma once
/// @file HeckbertHerf.h
/// @brief `--method hh`: Heckbert & Herf 1997, soft shadows accumulated from hard shadows into
/// receiver textures (the paper's "radiance textures"), for lightmap receivers.
///
/// For every receiver polygon (a lightmap triangle with its texel layout) and every light sample
/// the texels use, the blockers are projected from the sample onto the polygon's plane, mapped
/// into texel space by the polygon's affine parametrization (the paper's pyramid-to-box
/// transformation with the polygon's own parallelogram), and scan-converted: a texel whose centre
/// a projected blocker covers is in that sample's hard shadow. As in the paper, blockers are
/// clipped to the slab between the polygon's plane and the plane through the sample parallel to
/// it (z_u in (1 - epsilon, infinity) of Section 3.5), here with the rule's receiver epsilon, so
/// the polygon and anything on its plane cast no shadow on it. The blockers stream, one chunk at a
/// time; the result is a bit per texel receiver and sample (the same masks as every other method,
/// so the irradiance of Equation 2 is the same sum over visible samples).
///
/// Approximate at texel edges by nature: the hard shadow is sampled at the texel centre on the
/// polygon's plane, where the exact methods use the receiver itself (clamped into the polygon for
/// texels the polygon only partly covers), and scan conversion decides centres on an edge of a
/// projected blocker by its own test, not by the blocking rule. A sample behind the polygon's
/// plane (Section 3.6's back-face test) is not projected and counts as blocked: a closed surface
/// blocks it from behind (where the rule agrees), and it brings no irradiance either way.

#include "bake/rule/BlockingRule.h"
#include "bake/light/Light.h"
#include "receivers/LightmapReceivers.h"
#include "bake/cast/VisibilityMasks.h"
#include "receivers/ReceiverSet.h"
#include "stream/AlphaTable.h"
#include "stream/TriangleSource.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <span>

namespace penumbra {

struct HeckbertHerfStats {
    uint64_t polygons = 0;        ///< receiver polygons with at least one receiver
    uint64_t projections = 0;     ///< (polygon, sample, blocker) triples projected
    uint64_t coveredTexels = 0;   ///< texel centres found inside a projected blocker
    uint64_t trianglesRead = 0;
    double seconds = 0;
};

/// @brief Casts every relation of @p receivers, whose polygons and texels are @p polygons
/// (ReceiverKind::receiverPolygons(), for these receivers: entry i belongs to receiver i).
/// @param blockers read once, from the start (rewound)
/// @param alpha the bake's cut-outs: a cut-out blocker shadows a texel from a sample only where
/// the segment between them meets an opaque part of it (AlphaTable::lookup()); null draws
/// cut-outs as opaque triangles
VisibilityMasks castHeckbertHerf(const LightSamples& samples, const ReceiverSet& receivers,
                                 std::span<const uint32_t> sampleSets, TriangleSource& blockers,
                                 const ReceiverEpsilon& epsilon, const ReceiverPolygons& polygons,
                                 HeckbertHerfStats* stats = nullptr, const std::function<void(uint64_t)>& progress = {},
                                 const AlphaTable* alpha = nullptr);

/// @brief The stats JSON's "hh" section.
nlohmann::json heckbertHerfStatsJson(const HeckbertHerfStats& stats);

}  // namespace penumbra
