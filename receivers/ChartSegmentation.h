#pragma once
/// @file ChartSegmentation.h
/// @brief Cutting a mesh into charts for a generated lightmap atlas: connected groups of
/// triangles whose normals stay within a cone, so that each chart projects onto one plane with
/// little stretch and no fold.
///
/// Charts grow from seeds, largest triangle first, across manifold edges (MeshTopology.h), in
/// breadth-first order; a triangle joins when its normal is within the cone of the chart's
/// area-weighted mean normal at that moment. Degenerate (zero-area) triangles join the chart of
/// a triangle that shares a vertex with them (the first in index order), or form their own.
/// Charts smaller than a threshold then merge into the neighbour they share the longest border
/// with, when every triangle of the union stays within the cone plus kChartSlackDeg of the
/// union's mean normal; each chart costs a gutter in the atlas, so specks are worth merging.
/// Everything is in index order and single-threaded per mesh: the result is deterministic.

#include "receivers/MeshTopology.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

/// Slack over the growth cone allowed for the final chart (its mean normal moves as it grows)
/// and for merges.
inline constexpr double kChartSlackDeg = 10.0;

/// @brief A mesh prepared for segmentation: welded connectivity, unit face normals (zero for
/// degenerate triangles) and face areas, in double precision.
struct ChartSurface {
    explicit ChartSurface(const IndexedMesh& mesh);
    const IndexedMesh& mesh;
    MeshTopology topology;
    std::vector<glm::dvec3> normal;
    std::vector<double> area;
    bool degenerate(uint32_t t) const { return normal[t] == glm::dvec3(0.0); }
};

/// @brief Segments the triangles @p triangles of @p surface (the others are treated as absent:
/// charts never grow into them) into charts within @p coneDeg, then merges charts whose area is
/// below @p smallArea (world units squared; 0: no merging).
/// @return the charts, each its triangles in ascending order; every given triangle is in
///         exactly one chart.
std::vector<std::vector<uint32_t>> segmentCharts(const ChartSurface& surface, std::span<const uint32_t> triangles,
                                                 double coneDeg, double smallArea);

/// @brief The area-weighted mean unit normal of @p triangles (+z when they are all degenerate).
glm::dvec3 meanNormal(const ChartSurface& surface, std::span<const uint32_t> triangles);

}  // namespace penumbra
