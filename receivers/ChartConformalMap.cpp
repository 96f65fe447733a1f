#include "receivers/ChartConformalMap.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

constexpr int kMaxIterations = 2000;
constexpr double kTolerance = 1e-10;  ///< relative norm of the normal equations' residual
constexpr double kMinAreaRatio = 0.25;  ///< mapped area / surface area below which a map is refused

/// One triangle's residual coefficients: r1 = sum a_j u_j - b_j v_j, r2 = sum b_j u_j + a_j v_j.
struct Row {
    uint32_t c[3];
    double a[3], b[3];
};

/// The residual rows of the chart's non-degenerate triangles, over the unknowns @p unknownOf
/// (per chart vertex).
std::vector<Row> conformalRows(const ChartSurface& surface, const Chart& chart, const std::vector<uint32_t>& unknownOf) {
    const IndexedMesh& mesh = surface.mesh;
    std::vector<Row> rows;
    for (size_t i = 0; i < chart.triangles.size(); ++i) {
        const uint32_t t = chart.triangles[i];
        if (surface.degenerate(t)) continue;
        const glm::dvec3 p0(mesh.position[mesh.indices[3 * size_t(t)]]), p1(mesh.position[mesh.indices[3 * size_t(t) + 1]]),
            p2(mesh.position[mesh.indices[3 * size_t(t) + 2]]);
        // The triangle in its own plane: p0 at the origin, p1 on the x axis, counter-clockwise.
        const glm::dvec3 e1 = p1 - p0, e2 = p2 - p0;
        const double length = glm::length(e1);
        const glm::dvec3 x = e1 / length, y = glm::normalize(glm::cross(surface.normal[t], x));
        const glm::dvec2 q[3] = {{0, 0}, {length, 0}, {glm::dot(e2, x), glm::dot(e2, y)}};
        const double scale = 1.0 / std::sqrt(2.0 * surface.area[t]);
        Row row;
        for (int j = 0; j < 3; ++j) {
            const glm::dvec2 w = q[(j + 2) % 3] - q[(j + 1) % 3];
            row.c[j] = unknownOf[chart.corners[i][size_t(j)]];
            row.a[j] = w.x * scale, row.b[j] = w.y * scale;
        }
        rows.push_back(row);
    }
    return rows;
}

/// r = A x (two residuals per row; x holds u then v per vertex, interleaved).
void apply(const std::vector<Row>& rows, const std::vector<double>& x, std::vector<double>& r) {
    for (size_t i = 0; i < rows.size(); ++i) {
        const Row& row = rows[i];
        double r1 = 0, r2 = 0;
        for (int j = 0; j < 3; ++j) {
            const double u = x[2 * size_t(row.c[j])], v = x[2 * size_t(row.c[j]) + 1];
            r1 += row.a[j] * u - row.b[j] * v;
            r2 += row.b[j] * u + row.a[j] * v;
        }
        r[2 * i] = r1, r[2 * i + 1] = r2;
    }
}

/// g = A^T r, zero at the pinned vertices.
void applyTransposed(const std::vector<Row>& rows, const std::vector<double>& r, const uint32_t (&pins)[2], std::vector<double>& g) {
    std::fill(g.begin(), g.end(), 0.0);
    for (size_t i = 0; i < rows.size(); ++i) {
        const Row& row = rows[i];
        for (int j = 0; j < 3; ++j) {
            g[2 * size_t(row.c[j])] += row.a[j] * r[2 * i] + row.b[j] * r[2 * i + 1];
            g[2 * size_t(row.c[j]) + 1] += -row.b[j] * r[2 * i] + row.a[j] * r[2 * i + 1];
        }
    }
    for (uint32_t p : pins) g[2 * size_t(p)] = g[2 * size_t(p) + 1] = 0.0;
}

double dot(const std::vector<double>& a, const std::vector<double>& b) {
    double sum = 0;
    for (size_t i = 0; i < a.size(); ++i) sum += a[i] * b[i];
    return sum;
}

/// CGLS: minimizes |A x|^2 over the free entries of @p x, from its value.
void solve(const std::vector<Row>& rows, const uint32_t (&pins)[2], std::vector<double>& x) {
    std::vector<double> r(2 * rows.size()), s(x.size()), q(r.size());
    apply(rows, x, r);
    for (double& e : r) e = -e;
    applyTransposed(rows, r, pins, s);
    std::vector<double> p = s;
    double gamma = dot(s, s);
    const double stop = kTolerance * kTolerance * gamma;
    for (int iteration = 0; iteration < kMaxIterations && gamma > stop && gamma > 0; ++iteration) {
        apply(rows, p, q);
        const double qq = dot(q, q);
        if (!(qq > 0)) break;
        const double alpha = gamma / qq;
        for (size_t i = 0; i < x.size(); ++i) x[i] += alpha * p[i];
        for (size_t i = 0; i < r.size(); ++i) r[i] -= alpha * q[i];
        applyTransposed(rows, r, pins, s);
        const double next = dot(s, s);
        for (size_t i = 0; i < p.size(); ++i) p[i] = s[i] + (next / gamma) * p[i];
        gamma = next;
    }
}

double cross2(glm::dvec2 a, glm::dvec2 b) { return a.x * b.y - a.y * b.x; }

}  // namespace

bool conformalMap(const ChartSurface& surface, Chart& chart) {
    const size_t n = chart.uv.size();
    if (n < 4) return false;  // a triangle is already conformal
    // One unknown per welded position: loaders split vertices at seams, and a chart held
    // together only through positions would otherwise fall apart into unpinned pieces.
    std::vector<uint32_t> weld(n), order(n), unknownOf(n);
    for (size_t v = 0; v < n; ++v) weld[v] = surface.topology.weld[chart.vertices[v]], order[v] = uint32_t(v);
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return weld[a] != weld[b] ? weld[a] < weld[b] : a < b; });
    uint32_t unknowns = 0;
    for (size_t i = 0; i < n; ++i) {
        if (i > 0 && weld[order[i]] != weld[order[i - 1]]) ++unknowns;
        unknownOf[order[i]] = unknowns;
    }
    ++unknowns;
    const std::vector<Row> rows = conformalRows(surface, chart, unknownOf);
    if (rows.empty()) return false;
    // Pins: the vertices farthest apart along the planar chart's long side (its x axis).
    uint32_t low = 0, high = 0;
    for (uint32_t v = 0; v < n; ++v) {
        if (chart.uv[v].x < chart.uv[low].x) low = v;
        if (chart.uv[v].x > chart.uv[high].x) high = v;
    }
    const uint32_t pins[2] = {unknownOf[low], unknownOf[high]};
    if (pins[0] == pins[1]) return false;
    std::vector<double> x(2 * size_t(unknowns));
    for (size_t v = 0; v < n; ++v) x[2 * size_t(unknownOf[v])] = chart.uv[v].x, x[2 * size_t(unknownOf[v]) + 1] = chart.uv[v].y;
    solve(rows, pins, x);

    std::vector<glm::dvec2> uv(n);
    for (size_t v = 0; v < n; ++v) uv[v] = glm::dvec2(x[2 * size_t(unknownOf[v])], x[2 * size_t(unknownOf[v]) + 1]);
    double flat = 0;
    for (size_t i = 0; i < chart.corners.size(); ++i) {
        const auto& c = chart.corners[i];
        const double area2 = cross2(uv[c[1]] - uv[c[0]], uv[c[2]] - uv[c[0]]);
        if (!std::isfinite(area2)) return false;
        if (!surface.degenerate(chart.triangles[i]) && !(area2 > 0)) return false;  // turned over
        flat += 0.5 * std::abs(area2);
    }
    // A map that shrinks the chart to a fraction of its area has collapsed (it lost a pin's hold).
    if (!(flat > kMinAreaRatio * chart.area)) return false;
    const double scale = std::sqrt(chart.area / flat);
    for (glm::dvec2& p : uv) p *= scale;
    chart.uv = std::move(uv);
    chart.flatArea = chart.area;
    return true;
}

}  // namespace penumbra
