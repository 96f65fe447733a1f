#include "receivers/LightmapAtlas.h"

#include "stream/util/Progress.h"

#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

/// The density the packing will end near: the given one, or a fixed-size atlas about two-thirds full.
double expectedDensity(std::span<const IndexedMesh> meshes, const AtlasPackOptions& pack) {
    if (pack.texelsPerUnit > 0) return pack.texelsPerUnit;
    double area = 0;
    for (const IndexedMesh& mesh : meshes) area += surfaceArea(mesh);
    return area > 0 ? std::sqrt(0.66 * double(pack.width) * pack.height / area) : 1.0;
}

/// @p mesh with one vertex per (chart, chart vertex) and uv1 from the packing.
IndexedMesh splitAlongCharts(const IndexedMesh& mesh, std::span<const Chart> charts, std::span<const ChartPlacement> placement,
                             const AtlasPacking& packing, uint32_t firstChart, std::vector<uint32_t>& chartOf) {
    IndexedMesh out;
    out.name = mesh.name;
    out.indices.resize(mesh.indices.size());
    chartOf.assign(mesh.triangleCount(), 0);
    const glm::dvec2 size(packing.width, packing.height);
    for (size_t c = 0; c < charts.size(); ++c) {
        const Chart& chart = charts[c];
        const uint32_t base = uint32_t(out.position.size());
        for (size_t v = 0; v < chart.vertices.size(); ++v) {
            const uint32_t source = chart.vertices[v];
            out.position.push_back(mesh.position[source]);
            if (!mesh.normal.empty()) out.normal.push_back(mesh.normal[source]);
            if (!mesh.uv0.empty()) out.uv0.push_back(mesh.uv0[source]);
            out.uv1.emplace_back(atlasTexel(chart, placement[c], packing.texelsPerUnit, v) / size);
        }
        for (size_t i = 0; i < chart.triangles.size(); ++i) {
            const uint32_t t = chart.triangles[i];
            chartOf[t] = firstChart + uint32_t(c);
            for (int k = 0; k < 3; ++k) out.indices[3 * size_t(t) + k] = base + chart.corners[i][k];
        }
    }
    return out;
}

/// Adds each non-degenerate triangle's stretch (area-weighted) to @p sum and @p weight.
void addStretch(const IndexedMesh& mesh, glm::dvec2 size, double& sum, double& weight, double& worst) {
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        const uint32_t* i = &mesh.indices[3 * t];
        const glm::dvec3 e1 = glm::dvec3(mesh.position[i[1]]) - glm::dvec3(mesh.position[i[0]]);
        const glm::dvec3 e2 = glm::dvec3(mesh.position[i[2]]) - glm::dvec3(mesh.position[i[0]]);
        const glm::dvec3 n = glm::cross(e1, e2);
        const double area = 0.5 * glm::length(n), length = glm::length(e1);
        if (!(area > 0) || !(length > 0)) continue;
        // The triangle in its own plane: q1 = (|e1|, 0), q2 = (e2.x, e2.y); J maps q to uv texels.
        const glm::dvec3 x = e1 / length, y = glm::cross(glm::normalize(n), x);
        const double q2x = glm::dot(e2, x), q2y = glm::dot(e2, y);
        const glm::dvec2 d1 = (glm::dvec2(mesh.uv1[i[1]]) - glm::dvec2(mesh.uv1[i[0]])) * size;
        const glm::dvec2 d2 = (glm::dvec2(mesh.uv1[i[2]]) - glm::dvec2(mesh.uv1[i[0]])) * size;
        const glm::dvec2 column0 = d1 / length, column1 = (d2 - column0 * q2x) / q2y;
        const double frobenius = glm::dot(column0, column0) + glm::dot(column1, column1);
        const double det = std::abs(column0.x * column1.y - column0.y * column1.x);
        if (!(det > 0)) continue;
        const double s1 = std::sqrt(0.5 * (frobenius + std::sqrt(std::max(0.0, frobenius * frobenius - 4 * det * det))));
        const double ratio = s1 * s1 / det;  // s1 / s2 with s2 = det / s1
        sum += area * ratio, weight += area, worst = std::max(worst, ratio);
    }
}

}  // namespace

double surfaceArea(const IndexedMesh& mesh) {
    double area = 0;
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        const glm::dvec3 a(mesh.position[mesh.indices[3 * t]]), b(mesh.position[mesh.indices[3 * t + 1]]),
            c(mesh.position[mesh.indices[3 * t + 2]]);
        const double x = 0.5 * glm::length(glm::cross(b - a, c - a));
        if (std::isfinite(x)) area += x;
    }
    return area;
}

LightmapAtlas buildLightmapAtlas(std::span<const IndexedMesh> meshes, const AtlasOptions& options) {
    const double density = expectedDensity(meshes, options.pack);
    ChartLimits limits;
    limits.coneDeg = options.coneDeg;
    limits.smallArea = smallChartTexels(options.pack.padding) / (density * density);
    double area = 0;
    for (const IndexedMesh& mesh : meshes) area += surfaceArea(mesh);
    limits.largeExtent = kLargeChartExtent * std::sqrt(area);
    std::vector<std::vector<Chart>> perMesh(meshes.size());
    tbb::parallel_for(size_t(0), meshes.size(),
                      [&](size_t m) { perMesh[m] = makeCharts(meshes[m], uint32_t(m), limits); });
    std::vector<Chart> charts;
    for (std::vector<Chart>& list : perMesh)
        for (Chart& chart : list) charts.push_back(std::move(chart));

    // The packing is most of an atlas's time (seconds for a few thousand charts): a phase of its own.
    ProgressReporter progress("atlas", expectedPlacements(charts.size(), options.pack), options.quiet);
    AtlasPackOptions pack = options.pack;
    pack.progress = &progress;
    const AtlasPacking packing = packAtlas(charts, pack);
    // The estimate counts ten packings; a bisection that took fewer, or ended some early, is done.
    if (progress.workDone() < progress.totalWork()) progress.update(progress.totalWork() - progress.workDone());
    progress.done();
    LightmapAtlas atlas;
    atlas.charts = uint32_t(charts.size());
    if (packing.width == 0) return atlas;
    atlas.width = packing.width, atlas.height = packing.height;
    atlas.texelsPerUnit = packing.texelsPerUnit, atlas.densityLowered = packing.densityLowered;
    atlas.meshes.resize(meshes.size()), atlas.chartOf.resize(meshes.size());
    size_t first = 0;
    for (size_t m = 0; m < meshes.size(); ++m) {
        const size_t count = perMesh[m].size();
        atlas.meshes[m] = splitAlongCharts(meshes[m], std::span(charts).subspan(first, count),
                                           std::span(packing.placement).subspan(first, count), packing, uint32_t(first),
                                           atlas.chartOf[m]);
        first += count;
    }
    double sum = 0, weight = 0, worst = 1;
    for (const IndexedMesh& mesh : atlas.meshes) addStretch(mesh, glm::dvec2(atlas.width, atlas.height), sum, weight, worst);
    if (weight > 0) atlas.meanStretch = sum / weight, atlas.maxStretch = worst;
    return atlas;
}

}  // namespace penumbra
