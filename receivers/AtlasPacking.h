#pragma once
/// @file AtlasPacking.h
/// @brief Packing flattened charts (ChartParameterization.h) of several meshes into one
/// lightmap atlas, with a gutter that keeps every chart's dilation padding its own.
///
/// At a density of s texels per world unit each chart becomes a texel mask: per row, the span of
/// texels its triangles touch (conservatively: a texel within kMaskSlack texels of a triangle
/// counts, so float rounding of the UVs cannot reach outside the mask). The mask grown by
/// `padding` texels (Chebyshev) is the chart's reservation; reservations never intersect, so
/// the texels two charts cover are at least 2 * padding + 1 apart, and `padding` rings of
/// dilation (dilateLightmap) from either side never meet. Reservations may hang over the atlas
/// border (lightmaps are sampled clamped), masks may not.
///
/// Charts are placed largest first (bounding rectangle area, then index) at the lowest, then
/// leftmost, free position, as given or turned a quarter, whichever ends lower (bottom-left
/// fill on a bitmap; holes left by earlier charts are filled by later ones). The atlas size:
/// - fixed size: the largest density that fits, by bisection;
/// - fixed density: the smallest area over a few candidate widths (powers of two when asked),
///   and, if no candidate fits within maxSide, the largest density that fits maxSide x maxSide.
/// Masks are made in parallel, each in its own slot; placement is sequential, so the result does
/// not depend on the thread count.

#include "receivers/ChartParameterization.h"

#include <glm/vec2.hpp>

#include <cstdint>
#include <cstddef>
#include <span>
#include <vector>

namespace penumbra {

class ProgressReporter;

/// @brief How big the atlas is and how far apart its charts are.
struct AtlasPackOptions {
    int padding = 4;            ///< dilation rings per chart, kept free of other charts
    double texelsPerUnit = 0;   ///< > 0: this density, the atlas size is chosen
    int width = 0, height = 0;  ///< with texelsPerUnit == 0: this size, the density is chosen
    int maxSide = 16384;        ///< largest atlas side when the size is chosen
    bool powerOfTwo = false;    ///< chosen sides are powers of two
    /// Counts one unit per chart placed, over every packing tried (expectedPlacements() of them
    /// is the estimate); may throw Cancelled, which unwinds the packing. Null: none.
    ProgressReporter* progress = nullptr;
};

/// @brief About how many chart placements packAtlas() makes for @p charts charts: a fixed size
/// bisects the density (about ten packings), a fixed density tries a few widths.
uint64_t expectedPlacements(size_t charts, const AtlasPackOptions& options);

/// @brief Where one chart goes: its mask's lower corner in the atlas, and how many quarter
/// turns (counter-clockwise, 0-3) it is turned by.
struct ChartPlacement {
    int x = 0, y = 0;
    int turns = 0;
};

/// @brief A packed atlas; width == 0 when the charts do not fit.
struct AtlasPacking {
    int width = 0, height = 0;
    double texelsPerUnit = 0;
    bool densityLowered = false;          ///< the fixed density did not fit in maxSide x maxSide
    std::vector<ChartPlacement> placement;  ///< per chart, in the order given
};

/// @brief Sub-texel offset of a chart inside its mask, and the slack of the conservative masks.
inline constexpr double kMaskOffset = 0.05, kMaskSlack = 0.01;

/// @brief Packs @p charts (of any meshes) into one atlas.
AtlasPacking packAtlas(std::span<const Chart> charts, const AtlasPackOptions& options);

/// @brief Atlas texel coordinates (x right, y down, in texels) of chart vertex @p vertex.
glm::dvec2 atlasTexel(const Chart& chart, const ChartPlacement& placement, double texelsPerUnit, size_t vertex);

}  // namespace penumbra
