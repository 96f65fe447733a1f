#pragma once
/// @file PolygonSpan.h
/// @brief The camera rasterizer's pixel test for a projected convex polygon, and the span of a
/// row that can pass it (CameraRasterizer::add()).
///
/// The pixel test decides coverage; the span only skips pixel centres that the test would
/// reject, so the receivers do not depend on it. tests/receivers/test_polygon_span.cpp pins that
/// on edges through pixel centres, near-axis edges and slivers.

#include <algorithm>
#include <cmath>

namespace penumbra {

/// The corner after @p i of a polygon of @p m corners, without `(i + 1) % m`: an integer
/// division per edge and pixel was 3 % of FLOWERS' scan.
inline int nextCorner(int i, int m) { return i + 1 == m ? 0 : i + 1; }

/// @brief Whether the point (@p px, @p py) is inside (or on an edge of) the convex polygon
/// (@p sx, @p sy) of @p m corners, whose signed area has the sign @p orient (+1 or -1).
[[gnu::always_inline]] inline bool insidePolygon(const double* sx, const double* sy, int m, double orient, double px, double py) {
    for (int i = 0; i < m; ++i) {
        const int j = nextCorner(i, m);
        if (!(orient * ((sx[j] - sx[i]) * (py - sy[i]) - (sy[j] - sy[i]) * (px - sx[i])) >= 0)) return false;
    }
    return true;
}

/// @brief A convex polygon's edges, set up once so that each row's span costs a multiply-add
/// per edge (CameraRasterizer::add() draws thin triangles of a dozen rows and a pixel or two
/// each, so the rows are most of its work).
///
/// Edge i (corners i, j) with dx = sx_j - sx_i and dy = sy_j - sy_i (as insidePolygon()
/// computes them) accepts px on row py when orient (dx (py - sy_i) - dy (px - sx_i)) >= 0: for
/// orient dy > 0 that is px <= e = sx_i + s (py - sy_i), s = dx / dy, and px >= e for
/// orient dy < 0. The test's value, four roundings from its real one, is off by at most
/// 3.1u (|dx (py - sy_i)| + |dy (px - sx_i)|) (u = 2^-53), which moves the crossing by
/// 3.1u (|s| |py - sy_i| + |px - sx_i|); the computed e (s, the difference, the product and the
/// sum each rounded) is off by u |e| + 3.1u |s| |py - sy_i|. With R >= |py - sy_i| over the
/// rows and @p pxMax >= |px| over the pixels, widening e by 16u (|sx_i| + |s| R + pxMax) covers
/// both, and @p slack (a hundredth of a pixel: the span's conversion to columns rounds too) is
/// added. An edge with dy = 0 leaves the test the value orient dx (py - sy_i) exactly: a row on
/// its outside is empty.
struct PolygonSpans {
    /// Per edge: corner i's x and y, the slope s, and the widening. Edges [0, upper) bound the
    /// span from above, edges [lower, 4) from below.
    double x[4], y[4], slope[4], widen[4];
    int upper = 0, lower = 4;
    /// Edges with dy = 0: corner i's y and orient dx.
    double flatY[4], flatDx[4];
    int flat = 0;
};

/// @brief Sets up @p out for the polygon (sx, sy) of @p m corners and orientation @p orient, on
/// rows with centres in [@p pyLo, @p pyHi] and pixels with |px| <= @p pxMax.
inline void setUpSpans(const double* sx, const double* sy, int m, double orient, double pyLo, double pyHi, double pxMax,
                       PolygonSpans& out, double slack = 0.01) {
    constexpr double u = 0x1p-53;
    out.upper = 0, out.lower = 4, out.flat = 0;
    for (int i = 0; i < m; ++i) {
        const int j = nextCorner(i, m);
        const double dx = sx[j] - sx[i], dy = sy[j] - sy[i];
        if (dy == 0) {
            out.flatY[out.flat] = sy[i], out.flatDx[out.flat++] = orient * dx;
            continue;
        }
        const int k = orient * dy > 0 ? out.upper++ : --out.lower;
        const double reach = std::max(std::abs(pyLo - sy[i]), std::abs(pyHi - sy[i]));
        out.x[k] = sx[i], out.y[k] = sy[i], out.slope[k] = dx / dy;
        out.widen[k] = 16 * u * (std::abs(sx[i]) + std::abs(out.slope[k]) * reach + pxMax) + slack;
    }
}

/// @brief Narrows [@p lo, @p hi] to the x of row centre @p py that can pass insidePolygon();
/// empty (lo > hi) when none can.
[[gnu::always_inline]] inline void rowSpan(const PolygonSpans& p, double py, double& lo, double& hi) {
    for (int k = 0; k < p.upper; ++k) hi = std::min(hi, p.x[k] + p.slope[k] * (py - p.y[k]) + p.widen[k]);
    for (int k = p.lower; k < 4; ++k) lo = std::max(lo, p.x[k] + p.slope[k] * (py - p.y[k]) - p.widen[k]);
    for (int k = 0; k < p.flat; ++k)
        if (p.flatDx[k] * (py - p.flatY[k]) < 0) lo = INFINITY;  // the whole row is outside this edge
}

}  // namespace penumbra
