#pragma once
// An independent check of a generated lightmap atlas: every triangle's UV footprint is
// rasterized conservatively (every texel it touches, separating-axis test) into a grid of chart
// ids, which shows overlapping charts, the gutter between charts and the atlas area used.

#include "receivers/LightmapAtlas.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace penumbra::test {

struct AtlasCoverage {
    uint64_t claimed = 0;       ///< texels some triangle touches
    uint64_t contested = 0;     ///< texels touched by two different charts
    int closest = INT32_MAX;    ///< smallest Chebyshev distance between texels of different charts
    double used() const { return double(claimed); }
};

/// Whether triangle @p t touches the closed square [x, x+1] x [y, y+1] (grown by @p slack).
inline bool touches(const glm::dvec2 (&t)[3], double x, double y, double slack) {
    const glm::dvec2 lo(x - slack, y - slack), hi(x + 1 + slack, y + 1 + slack);
    auto separated = [&](glm::dvec2 axis) {
        double a0 = INFINITY, a1 = -INFINITY, b0 = INFINITY, b1 = -INFINITY;
        for (const auto& p : t) a0 = std::min(a0, glm::dot(p, axis)), a1 = std::max(a1, glm::dot(p, axis));
        for (glm::dvec2 p : {lo, hi, glm::dvec2(lo.x, hi.y), glm::dvec2(hi.x, lo.y)})
            b0 = std::min(b0, glm::dot(p, axis)), b1 = std::max(b1, glm::dot(p, axis));
        return a1 < b0 || b1 < a0;
    };
    if (separated({1, 0}) || separated({0, 1})) return false;
    for (int i = 0; i < 3; ++i) {
        const glm::dvec2 e = t[(i + 1) % 3] - t[i];
        if (e != glm::dvec2(0.0) && separated({-e.y, e.x})) return false;
    }
    return true;
}

/// Chart id per texel (-1 none, -2 two charts) of @p atlas, from the meshes' uv1 as floats.
inline std::vector<int64_t> chartGrid(const LightmapAtlas& atlas, AtlasCoverage& coverage) {
    const int W = atlas.width, H = atlas.height;
    std::vector<int64_t> grid(size_t(W) * H, -1);
    for (size_t m = 0; m < atlas.meshes.size(); ++m) {
        const IndexedMesh& mesh = atlas.meshes[m];
        for (size_t t = 0; t < mesh.triangleCount(); ++t) {
            glm::dvec2 v[3];
            for (int k = 0; k < 3; ++k) v[k] = glm::dvec2(mesh.uv1[mesh.indices[3 * t + k]]) * glm::dvec2(W, H);
            const glm::dvec2 lo = glm::min(glm::min(v[0], v[1]), v[2]), hi = glm::max(glm::max(v[0], v[1]), v[2]);
            for (int y = std::max(0, int(std::floor(lo.y)) - 1); y <= std::min(H - 1, int(hi.y) + 1); ++y)
                for (int x = std::max(0, int(std::floor(lo.x)) - 1); x <= std::min(W - 1, int(hi.x) + 1); ++x) {
                    if (!touches(v, x, y, 1e-9)) continue;
                    int64_t& cell = grid[size_t(y) * W + x];
                    const int64_t chart = atlas.chartOf[m][t];
                    if (cell == -1) cell = chart, ++coverage.claimed;
                    else if (cell != chart && cell != -2) cell = -2, ++coverage.contested;
                }
        }
    }
    return grid;
}

/// Coverage, overlaps and the closest approach of two charts (searched up to @p reach texels).
inline AtlasCoverage checkAtlas(const LightmapAtlas& atlas, int reach) {
    AtlasCoverage coverage;
    const std::vector<int64_t> grid = chartGrid(atlas, coverage);
    const int W = atlas.width, H = atlas.height;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const int64_t c = grid[size_t(y) * W + x];
            if (c < 0) continue;
            for (int dy = -reach; dy <= reach; ++dy)
                for (int dx = -reach; dx <= reach; ++dx) {
                    const int nx = x + dx, ny = y + dy;
                    if (nx < 0 || ny < 0 || nx >= W || ny >= H) continue;
                    const int64_t o = grid[size_t(ny) * W + nx];
                    if (o >= 0 && o != c) coverage.closest = std::min(coverage.closest, std::max(std::abs(dx), std::abs(dy)));
                }
        }
    return coverage;
}

}  // namespace penumbra::test
