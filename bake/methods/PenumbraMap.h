#pragma once
/// @file PenumbraMap.h
/// @brief `--method penumbra-map`: Wyman & Hansen's penumbra maps (2003), an approximate preview.
///
/// Per light, from its centre (a sun: along its central direction), over the streamed geometry
/// and in memory bounded by the maps (never by the triangle count):
///  1. a shadow map (LightView.h): per texel the nearest depth, and with the default lookup the
///     nearest four surfaces (layers), so blockers hidden from the centre behind nearer ones count;
///  2. the lookup, one of two (bake.penumbra_map_lookup):
///     - "backprojection" (default, Backprojection.h): per-layer depth pyramids, and per receiver
///       the shadow-map texels around it backprojected onto a grid over the light's outline; the
///       visible fraction is the share of the light left. It gives inner and outer penumbrae and
///       combines overlapping blockers, at a cost per receiver bounded by the pyramid, whatever
///       the light's sample count;
///     - "wyman-hansen", the paper's: a penumbra map, built in a second pass from the silhouette
///       edges seen from the light's centre: an edge is a silhouette where the shadow map, 1.5
///       texels beyond the edge on the side away from its triangle, holds a surface farther than
///       the edge by more than the bias, while the edge itself is the nearest surface. This needs
///       no adjacency, so triangle soups work and nothing but the maps is held. Along each
///       silhouette run a sheet, closed by cones at its ends, is drawn: at angular distance a
///       from the edge, the cone of a vertex at depth Z_v reaches depth
///       Z_F = Z_v / (1 - a Z_v / L_r) (orthographic: Z_v + a / tan r), and the texel, whose
///       nearest surface is at Z_P, gets the paper's intensity I = (Z_F - Z_v) / (Z_P - Z_v),
///       smoothed to 3 I^2 - 2 I^3; the darkest value wins. L_r is the light's half-width across
///       the edge, seen from the centre. A receiver is in full shadow when the shadow map holds a
///       surface nearer than it by more than the bias (slope-scaled); otherwise its visible
///       fraction is its penumbra-map texel. Umbrae are the hard shadow from the centre and only
///       outer penumbrae exist, so shadows come out larger and darker than the exact ones;
///       overlapping penumbrae take the darkest, not the product.
///
/// The result is a visible fraction per receiver and light, not per-sample masks; irradiance is
/// the unoccluded irradiance scaled by it (ReceiverShader::shadeVisibleFraction).

#include "bake/rule/BlockingRule.h"
#include "bake/light/Light.h"
#include "receivers/ReceiverSet.h"
#include "stream/AlphaTable.h"
#include "stream/util/JsonParams.h"
#include "stream/TriangleSource.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <memory>
#include <span>
#include <vector>

namespace penumbra {

/// @brief Scene keys bake.penumbra_map_resolution, bake.penumbra_map_bias,
/// bake.penumbra_map_lookup, bake.penumbra_map_taps (and the flags of the same names).
struct PenumbraMapOptions {
    /// How a receiver's visible fraction is read from the maps.
    enum class Lookup {
        Backprojection,  ///< the shadow map backprojected onto the light (Backprojection.h): inner and outer penumbrae
        WymanHansen,     ///< the paper's penumbra map: the hard shadow from the centre and outer penumbrae only
    };
    int resolution = 1024;      ///< texels per side of a fitted view; cube faces get half
    double bias = 1.5;          ///< depth bias in texels of the shadow map, scaled by the receiver's slope
    Lookup lookup = Lookup::Backprojection;
    /// Backprojection: texels read each side of a receiver (Backprojection.h). 3 reads at most 49
    /// texels per layer; 2 reads 25 in about two thirds of the lookup time, for mean |dV| about
    /// 10 % higher on the examples and twice the error on the analytic edge (docs/BENCHMARKS.md).
    int taps = 3;
    /// The bake's cut-outs (alpha ids in Triangle::flags): the shadow map keeps a cut-out's texel
    /// only where it is opaque. Null: cut-outs are drawn as opaque triangles.
    const AlphaTable* alpha = nullptr;
    /// Bytes of one light's maps (depth and penumbra, float, at most six cube faces).
    uint64_t mapBytes() const;
};

/// @brief Reads bake.penumbra_map_resolution, bake.penumbra_map_bias, bake.penumbra_map_lookup
/// ("backprojection" or "wyman-hansen") and bake.penumbra_map_taps (1..8); defaults when absent.
/// @throw InputError naming the key for a value out of range
PenumbraMapOptions penumbraMapOptions(const JsonParams& bake);

struct PenumbraMapStats {
    int views = 0;                ///< views drawn (a light's maps kept from the last cast are not drawn again)
    int mapsReused = 0;           ///< lights whose maps came from the last cast (PenumbraMapCache)
    /// Lights whose maps were drawn again in a wider view: blockers that can shadow the receivers
    /// lay outside the view fitted to their directions (LightView.h, ShadowReach)
    int viewsWidened = 0;
    uint64_t mapBytes = 0;        ///< the largest light's maps
    double shadowSeconds = 0;     ///< pass 1: shadow maps
    double penumbraSeconds = 0;   ///< pass 2 (wyman-hansen): silhouettes, cones and sheets; backprojection: the depth pyramid
    double lookupSeconds = 0;
    uint64_t silhouetteRuns = 0;  ///< runs of silhouette edge drawn as sheets
    uint64_t trianglesRead = 0;
};

/// @brief One light's finished maps, kept from one cast to the next. An antialiasing pass's
/// receivers lie among the first pass's, so the maps drawn for those serve them, unless a
/// receiver falls outside their views; then the light's maps are drawn again, fitted to the new
/// receivers. One light's maps at most, so the memory plan's count holds.
class PenumbraMapCache {
public:
    PenumbraMapCache();
    ~PenumbraMapCache();
    PenumbraMapCache(PenumbraMapCache&&) noexcept;
    PenumbraMapCache& operator=(PenumbraMapCache&&) noexcept;
    struct Kept;                  ///< the light and its maps (PenumbraMap.cpp)
    std::unique_ptr<Kept> kept;   ///< null until a cast has kept one
};

/// @brief The visible fraction of every light for every receiver, receiver-major (r * lights + l).
/// @param sampleSets unused: the method has no samples (kept for a common caster signature)
/// @param epsilon the rule's receiver epsilon, the smallest depth bias
/// @param blockers read once or twice per light, from the start (rewound)
/// @param observe if set, shown every chunk of the first read as read (before non-casting
/// triangles are dropped), so that a receiver kind that watches the stream needs no read of its own
/// @param cache if set, the light it holds is done first, from its maps when they cover every
/// receiver, and the last light's maps are left in it
std::vector<float> castPenumbraMap(const LightSamples& samples, const ReceiverPoints& receivers,
                                   std::span<const uint32_t> sampleSets, TriangleSource& blockers,
                                   const ReceiverEpsilon& epsilon, const PenumbraMapOptions& options,
                                   PenumbraMapStats* stats = nullptr, const std::function<void(uint64_t)>& progress = {},
                                   const std::function<void(std::span<const Triangle>)>& observe = {},
                                   PenumbraMapCache* cache = nullptr);

/// @brief The stats JSON's "penumbra_map" section.
nlohmann::json penumbraMapStatsJson(const PenumbraMapStats& stats, const PenumbraMapOptions& options);

}  // namespace penumbra
