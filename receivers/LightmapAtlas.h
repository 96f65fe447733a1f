#pragma once
/// @file LightmapAtlas.h
/// @brief Lightmap UVs for meshes that have none (or none usable): the meshes are cut into
/// charts (ChartSegmentation.h), flattened (ChartParameterization.h) and packed together into
/// one atlas (AtlasPacking.h); each mesh comes back with its vertices split at chart borders and
/// the atlas coordinates in uv1 (glTF TEXCOORD_1).
///
/// Charts smaller than smallChartTexels(padding) texels at the expected density merge into a
/// neighbour where the normals allow it: below that, a chart's gutter costs more atlas than the
/// chart itself. Meshes are cut in parallel, each on its own; the result is the same for any
/// thread count.

#include "receivers/AtlasPacking.h"
#include "stream/IndexedMesh.h"

#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

inline constexpr double kDefaultChartConeDeg = 45.0;

/// @brief How to cut and pack.
struct AtlasOptions {
    double coneDeg = kDefaultChartConeDeg;  ///< growth cone of the charts
    AtlasPackOptions pack;                  ///< its progress is set by buildLightmapAtlas()
    bool quiet = true;                      ///< false: the packing shows an "[atlas]" phase on stderr
};

/// @brief Sprawling charts longer than this fraction of the side of a square of the meshes'
/// total area are cut (ChartLimits::largeExtent).
inline constexpr double kLargeChartExtent = 0.5;

/// @brief Area in texels below which a chart merges into a neighbour when it can.
inline double smallChartTexels(int padding) { return 16.0 * (padding + 1) * (padding + 1); }

/// @brief The generated atlas.
struct LightmapAtlas {
    int width = 0, height = 0;          ///< 0 when the charts do not fit (see AtlasPacking)
    double texelsPerUnit = 0;
    bool densityLowered = false;        ///< see AtlasPacking::densityLowered
    uint32_t charts = 0;
    /// Stretch of the map from surface to atlas: per triangle the ratio of the singular values
    /// of its Jacobian (1 for a map that keeps angles), area-weighted mean and maximum.
    double meanStretch = 1, maxStretch = 1;
    std::vector<IndexedMesh> meshes;    ///< per input mesh: split vertices, uv1 = atlas UVs in [0, 1]
    std::vector<std::vector<uint32_t>> chartOf;  ///< per mesh and triangle: its chart (atlas-wide id)
};

/// @brief Cuts, flattens and packs @p meshes into one atlas.
LightmapAtlas buildLightmapAtlas(std::span<const IndexedMesh> meshes, const AtlasOptions& options);

/// @brief The area of @p mesh's triangles (non-finite ones skipped).
double surfaceArea(const IndexedMesh& mesh);

}  // namespace penumbra
