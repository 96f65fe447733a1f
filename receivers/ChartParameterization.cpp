#include "receivers/ChartParameterization.h"

#include "receivers/ChartConformalMap.h"

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace penumbra {
namespace {


double cross2(glm::dvec2 a, glm::dvec2 b) { return a.x * b.y - a.y * b.x; }

/// Andrew's monotone chain; counter-clockwise, no collinear points.
std::vector<glm::dvec2> convexHull(std::vector<glm::dvec2> p) {
    std::sort(p.begin(), p.end(), [](glm::dvec2 a, glm::dvec2 b) { return a.x != b.x ? a.x < b.x : a.y < b.y; });
    p.erase(std::unique(p.begin(), p.end()), p.end());
    if (p.size() < 3) return p;
    std::vector<glm::dvec2> hull(2 * p.size());
    size_t k = 0;
    for (size_t i = 0; i < p.size(); ++i) {
        while (k >= 2 && cross2(hull[k - 1] - hull[k - 2], p[i] - hull[k - 2]) <= 0) --k;
        hull[k++] = p[i];
    }
    for (size_t i = p.size() - 1, lower = k + 1; i-- > 0;) {
        while (k >= lower && cross2(hull[k - 1] - hull[k - 2], p[i] - hull[k - 2]) <= 0) --k;
        hull[k++] = p[i];
    }
    hull.resize(k - 1);
    return hull;
}

/// The unit direction of the x axis of the smallest-area rectangle around @p hull (rotating
/// calipers: one side of that rectangle lies on a hull edge).
glm::dvec2 smallestRectangleAxis(const std::vector<glm::dvec2>& hull) {
    glm::dvec2 best(1, 0);
    double bestArea = INFINITY;
    for (size_t i = 0; i < hull.size(); ++i) {
        const glm::dvec2 edge = hull[(i + 1) % hull.size()] - hull[i];
        const double length = glm::length(edge);
        if (!(length > 0)) continue;
        const glm::dvec2 x = edge / length, y(-x.y, x.x);
        double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
        for (glm::dvec2 p : hull) {
            x0 = std::min(x0, glm::dot(p, x)), x1 = std::max(x1, glm::dot(p, x));
            y0 = std::min(y0, glm::dot(p, y)), y1 = std::max(y1, glm::dot(p, y));
        }
        const double area = (x1 - x0) * (y1 - y0);
        if (area < bestArea * (1 - 1e-12)) bestArea = area, best = x;
    }
    return best;
}

/// Turns @p uv so that its smallest bounding rectangle is axis-aligned, wider than tall, with
/// its lower corner at the origin; a rotation, so triangles keep their winding.
glm::dvec2 alignToRectangle(std::vector<glm::dvec2>& uv) {
    const glm::dvec2 x = smallestRectangleAxis(convexHull(uv)), y(-x.y, x.x);
    glm::dvec2 lo(INFINITY), hi(-INFINITY);
    for (glm::dvec2& p : uv) {
        p = glm::dvec2(glm::dot(p, x), glm::dot(p, y));
        lo = glm::min(lo, p), hi = glm::max(hi, p);
    }
    glm::dvec2 size = uv.empty() ? glm::dvec2(0.0) : hi - lo;
    const bool turn = size.y > size.x;
    for (glm::dvec2& p : uv) {
        p -= lo;
        if (turn) p = glm::dvec2(size.y - p.y, p.x);  // a quarter turn
    }
    if (turn) size = glm::dvec2(size.y, size.x);
    return size;
}

/// Interval overlap of two triangles projected on @p axis, beyond @p tolerance.
bool overlapOnAxis(const glm::dvec2 (&a)[3], const glm::dvec2 (&b)[3], glm::dvec2 axis, double tolerance) {
    double a0 = INFINITY, a1 = -INFINITY, b0 = INFINITY, b1 = -INFINITY;
    for (int k = 0; k < 3; ++k) {
        a0 = std::min(a0, glm::dot(a[k], axis)), a1 = std::max(a1, glm::dot(a[k], axis));
        b0 = std::min(b0, glm::dot(b[k], axis)), b1 = std::max(b1, glm::dot(b[k], axis));
    }
    return a1 > b0 + tolerance && b1 > a0 + tolerance;
}

/// Separating-axis test of two triangles' interiors; @p tolerance is in the axes' units times
/// edge length (axes are not normalized), so touching along an edge is no overlap.
bool trianglesOverlap(const glm::dvec2 (&a)[3], const glm::dvec2 (&b)[3], double tolerance) {
    for (const auto* t : {&a, &b})
        for (int k = 0; k < 3; ++k) {
            const glm::dvec2 e = (*t)[(k + 1) % 3] - (*t)[k];
            const double length = glm::length(e);
            if (!(length > 0)) continue;
            if (!overlapOnAxis(a, b, glm::dvec2(-e.y, e.x) / length, tolerance)) return false;
        }
    return true;
}

/// Cuts @p triangles in two across their longest principal axis (the area-weighted covariance
/// of their centroids) and returns the connected parts of both halves; fewer than two parts when
/// the cut separates nothing.
std::vector<std::vector<uint32_t>> splitInTwo(const ChartSurface& surface, std::span<const uint32_t> triangles) {
    const IndexedMesh& mesh = surface.mesh;
    std::vector<glm::dvec3> centre(triangles.size());
    glm::dvec3 mean(0.0);
    double weight = 0;
    for (size_t i = 0; i < triangles.size(); ++i) {
        const uint32_t* v = &mesh.indices[3 * size_t(triangles[i])];
        centre[i] = (glm::dvec3(mesh.position[v[0]]) + glm::dvec3(mesh.position[v[1]]) + glm::dvec3(mesh.position[v[2]])) / 3.0;
        const double w = surface.area[triangles[i]] + 1e-300;
        mean += w * centre[i], weight += w;
    }
    mean /= weight;
    glm::dmat3 covariance(0.0);
    for (size_t i = 0; i < triangles.size(); ++i) {
        const glm::dvec3 d = centre[i] - mean;
        covariance += (surface.area[triangles[i]] + 1e-300) * glm::outerProduct(d, d);
    }
    // Power iteration from the covariance's longest column (never orthogonal to the dominant axis).
    glm::dvec3 axis = covariance[0];
    for (int k = 1; k < 3; ++k)
        if (glm::length(covariance[k]) > glm::length(axis)) axis = covariance[k];
    for (int iteration = 0; iteration < 32 && glm::length(axis) > 0; ++iteration) axis = glm::normalize(covariance * axis);
    std::vector<uint8_t> side(surface.normal.size(), 2);  // 2: not in this chart
    for (size_t i = 0; i < triangles.size(); ++i) side[triangles[i]] = glm::dot(centre[i] - mean, axis) < 0 ? 0 : 1;

    std::vector<std::vector<uint32_t>> parts;
    std::vector<uint8_t> done(surface.normal.size(), 0);
    for (uint32_t seed : triangles) {
        if (done[seed]) continue;
        std::vector<uint32_t> part{seed};
        done[seed] = 1;
        for (size_t head = 0; head < part.size(); ++head)
            for (int k = 0; k < 3; ++k) {
                const uint32_t u = surface.topology.across[3 * size_t(part[head]) + k];
                if (u != kNoTriangle && !done[u] && side[u] == side[seed]) done[u] = 1, part.push_back(u);
            }
        std::sort(part.begin(), part.end());
        parts.push_back(std::move(part));
    }
    return parts;
}

}  // namespace

bool chartOverlapsItself(const Chart& chart) {
    const size_t n = chart.corners.size();
    if (n < 2) return false;
    const double tolerance = 1e-9 * std::max({chart.size.x, chart.size.y, 1e-30});
    // A uniform grid of about one triangle per cell; a pair is tested in the cell holding the
    // lower corner of the intersection of their boxes, so once.
    const int cells = std::clamp(int(std::sqrt(double(n))), 1, 1024);
    const glm::dvec2 cellSize = glm::max(chart.size / double(cells), glm::dvec2(1e-300));
    std::vector<std::vector<uint32_t>> grid(size_t(cells) * cells);
    std::vector<glm::dvec2> lo(n), hi(n);
    auto cellOf = [&](glm::dvec2 p) { return glm::clamp(glm::ivec2(p / cellSize), glm::ivec2(0), glm::ivec2(cells - 1)); };
    for (size_t t = 0; t < n; ++t) {
        const auto& c = chart.corners[t];
        lo[t] = glm::min(glm::min(chart.uv[c[0]], chart.uv[c[1]]), chart.uv[c[2]]);
        hi[t] = glm::max(glm::max(chart.uv[c[0]], chart.uv[c[1]]), chart.uv[c[2]]);
        const glm::ivec2 a = cellOf(lo[t]), b = cellOf(hi[t]);
        for (int y = a.y; y <= b.y; ++y)
            for (int x = a.x; x <= b.x; ++x) grid[size_t(y) * cells + x].push_back(uint32_t(t));
    }
    for (size_t cell = 0; cell < grid.size(); ++cell) {
        const std::vector<uint32_t>& in = grid[cell];
        for (size_t i = 0; i < in.size(); ++i) {
            for (size_t j = i + 1; j < in.size(); ++j) {
                const uint32_t s = in[i], t = in[j];
                const glm::dvec2 l = glm::max(lo[s], lo[t]), h = glm::min(hi[s], hi[t]);
                if (l.x >= h.x - tolerance || l.y >= h.y - tolerance) continue;
                const glm::ivec2 owner = cellOf(l);
                if (size_t(owner.y) * cells + owner.x != cell) continue;
                glm::dvec2 a[3], b[3];
                for (int k = 0; k < 3; ++k) a[k] = chart.uv[chart.corners[s][k]], b[k] = chart.uv[chart.corners[t][k]];
                if (std::abs(cross2(a[1] - a[0], a[2] - a[0])) == 0 || std::abs(cross2(b[1] - b[0], b[2] - b[0])) == 0)
                    continue;  // no interior
                if (trianglesOverlap(a, b, tolerance)) return true;
            }
        }
    }
    return false;
}

bool projectChart(const ChartSurface& surface, std::span<const uint32_t> triangles, double limitDeg, Chart& chart) {
    const IndexedMesh& mesh = surface.mesh;
    const glm::dvec3 n = meanNormal(surface, triangles);
    const double limitCos = std::cos(std::min(limitDeg, 180.0) * std::numbers::pi / 180.0);
    chart.triangles.assign(triangles.begin(), triangles.end());
    chart.vertices.clear(), chart.uv.clear(), chart.corners.clear();
    chart.area = 0;
    for (uint32_t t : triangles) {
        if (!surface.degenerate(t) && glm::dot(surface.normal[t], n) < limitCos) return false;
        chart.area += surface.area[t];
    }
    // Basis (tangent, bitangent, n) right-handed, so front faces stay counter-clockwise.
    const glm::dvec3 axis = std::abs(n.x) <= std::abs(n.y) && std::abs(n.x) <= std::abs(n.z) ? glm::dvec3(1, 0, 0)
                            : std::abs(n.y) <= std::abs(n.z)                                  ? glm::dvec3(0, 1, 0)
                                                                                              : glm::dvec3(0, 0, 1);
    const glm::dvec3 tangent = glm::normalize(glm::cross(n, axis)), bitangent = glm::cross(n, tangent);
    const glm::dvec3 origin(mesh.position[mesh.indices[3 * size_t(triangles[0])]]);

    // Chart vertices: the mesh vertices its triangles use, ascending.
    for (uint32_t t : triangles)
        for (int k = 0; k < 3; ++k) chart.vertices.push_back(mesh.indices[3 * size_t(t) + k]);
    std::sort(chart.vertices.begin(), chart.vertices.end());
    chart.vertices.erase(std::unique(chart.vertices.begin(), chart.vertices.end()), chart.vertices.end());
    for (uint32_t v : chart.vertices) {
        const glm::dvec3 d = glm::dvec3(mesh.position[v]) - origin;
        chart.uv.emplace_back(glm::dot(d, tangent), glm::dot(d, bitangent));
    }
    chart.flatArea = 0;
    for (uint32_t t : triangles) {
        std::array<uint32_t, 3> corner{};
        for (int k = 0; k < 3; ++k)
            corner[k] = uint32_t(std::lower_bound(chart.vertices.begin(), chart.vertices.end(), mesh.indices[3 * size_t(t) + k]) -
                                 chart.vertices.begin());
        chart.corners.push_back(corner);
        chart.flatArea += 0.5 * std::abs(cross2(chart.uv[corner[1]] - chart.uv[corner[0]], chart.uv[corner[2]] - chart.uv[corner[0]]));
    }
    chart.size = alignToRectangle(chart.uv);
    return !chartOverlapsItself(chart);
}

std::vector<Chart> makeCharts(const IndexedMesh& mesh, uint32_t meshIndex, const ChartLimits& limits) {
    const ChartSurface surface(mesh);
    std::vector<uint32_t> all(mesh.triangleCount());
    for (size_t t = 0; t < all.size(); ++t) all[t] = uint32_t(t);
    std::vector<std::vector<uint32_t>> pending = segmentCharts(surface, all, limits.coneDeg, limits.smallArea);
    std::reverse(pending.begin(), pending.end());  // a stack that pops charts in segmentation order

    std::vector<Chart> charts;
    while (!pending.empty()) {
        const std::vector<uint32_t> next = std::move(pending.back());
        pending.pop_back();
        Chart chart;
        chart.mesh = meshIndex;
        // A single triangle never folds or overlaps itself: accept it whatever its normal.
        const double limit = next.size() == 1 ? 180.0 : limits.coneDeg + kChartSlackDeg;
        const bool flat = projectChart(surface, next, limit, chart);
        const bool sprawling = flat && next.size() > 1 && std::max(chart.size.x, chart.size.y) > limits.largeExtent &&
                               chart.flatArea < kSparseChartFill * chart.size.x * chart.size.y;
        if (flat && !sprawling) {
            // A conformal map unrolls what the projection squeezed, when it neither turns a
            // triangle over nor overlaps itself.
            Chart conformal = chart;
            if (conformalMap(surface, conformal)) {
                conformal.size = alignToRectangle(conformal.uv);
                if (!chartOverlapsItself(conformal)) chart = std::move(conformal);
            }
            charts.push_back(std::move(chart));
            continue;
        }
        std::vector<std::vector<uint32_t>> parts = splitInTwo(surface, next);
        if (parts.size() <= 1) {  // no progress: one chart per triangle
            parts.clear();
            for (uint32_t t : next) parts.push_back({t});
        }
        for (size_t i = parts.size(); i-- > 0;) pending.push_back(std::move(parts[i]));
    }
    return charts;
}

}  // namespace penumbra
