#pragma once
/// @file ChartParameterization.h
/// @brief Flattening charts (ChartSegmentation.h) for a lightmap atlas: each chart is projected
/// onto the plane of its mean normal, which keeps lengths within 1 / cos(cone) of the surface's,
/// checked not to fold or overlap itself, split when it does, and turned to its smallest
/// bounding rectangle.
///
/// A projected chart folds when a triangle turns more than the cone (plus kChartSlackDeg) from
/// the chart's normal, and overlaps itself when two of its projected triangles share interior
/// points (a spiral ramp, a surface that curls over). Such a chart is cut in two across its
/// longest principal axis, each connected part is projected again, and so on, down to single
/// triangles, which never fold or overlap. Long sprawling charts are cut the same way.

#include "receivers/ChartSegmentation.h"

#include <glm/vec2.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

/// @brief One flattened chart of one mesh.
struct Chart {
    uint32_t mesh = 0;                             ///< which of the atlas's meshes
    std::vector<uint32_t> triangles;               ///< triangles of that mesh, ascending
    std::vector<uint32_t> vertices;                ///< per chart vertex: the mesh vertex it copies
    std::vector<glm::dvec2> uv;                    ///< per chart vertex: plane coordinates in world units, in [0, size]
    std::vector<std::array<uint32_t, 3>> corners;  ///< per chart triangle: chart vertices
    glm::dvec2 size{0.0};                          ///< extent of uv (width >= height)
    double area = 0;                               ///< surface area (world units squared)
    double flatArea = 0;                           ///< area of the projected triangles
};

/// @brief What makes a good chart.
struct ChartLimits {
    double coneDeg = 45;      ///< growth cone of the segmentation
    double smallArea = 0;     ///< merge threshold (world units squared), see segmentCharts()
    /// Charts longer than this (world units) that fill less than kSparseChartFill of their
    /// bounding rectangle are cut in two: long sprawling charts leave holes no other chart fills.
    double largeExtent = INFINITY;
};

inline constexpr double kSparseChartFill = 0.6;

/// @brief Planar projection of @p triangles onto their mean normal's plane, turned to the
/// smallest bounding rectangle (wider than tall) with its corner at the origin.
/// @return false (and @p chart unspecified) when a triangle is more than @p limitDeg from the
///         mean normal or two projected triangles overlap.
bool projectChart(const ChartSurface& surface, std::span<const uint32_t> triangles, double limitDeg, Chart& chart);

/// @brief Whether two of @p chart's triangles share interior points (touching is not overlap).
bool chartOverlapsItself(const Chart& chart);

/// @brief Segments, flattens and splits one mesh into charts; each projection is relaxed into a
/// conformal map (ChartConformalMap.h) when that map is valid.
/// @return every triangle of the mesh in exactly one chart, in a deterministic order
std::vector<Chart> makeCharts(const IndexedMesh& mesh, uint32_t meshIndex, const ChartLimits& limits);

}  // namespace penumbra
