// The camera rasterizer's row spans (receivers/PolygonSpan.h): a span only skips pixel centres
// that the pixel test rejects, on the cases where the crossing and the test round differently.

#include "receivers/PolygonSpan.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <random>

using namespace penumbra;

namespace {

struct SpanTally {
    long accepted = 0;  ///< pixel centres the test accepts (all inside their row's span)
    long spanned = 0;   ///< pixel centres inside the spans (what the rasterizer tests)
    long dropped = 0;   ///< accepted centres outside their span (must stay 0)
};

/// Every row and pixel around polygon (sx, sy) of @p m corners, as CameraRasterizer::add()
/// converts a span to columns.
void checkPolygon(const double* sx, const double* sy, int m, double slack, SpanTally& tally) {
    double area = 0;
    for (int i = 0; i < m; ++i) area += sx[i] * sy[nextCorner(i, m)] - sx[nextCorner(i, m)] * sy[i];
    if (area == 0) return;
    const double orient = area > 0 ? 1.0 : -1.0;
    double xLo = INFINITY, xHi = -INFINITY, yLo = INFINITY, yHi = -INFINITY;
    for (int i = 0; i < m; ++i) xLo = std::min(xLo, sx[i]), xHi = std::max(xHi, sx[i]), yLo = std::min(yLo, sy[i]), yHi = std::max(yHi, sy[i]);
    const int x0 = int(std::floor(xLo)) - 2, x1 = int(std::ceil(xHi)) + 2;
    const int y0 = int(std::floor(yLo)) - 2, y1 = int(std::ceil(yHi)) + 2;
    PolygonSpans spans;
    setUpSpans(sx, sy, m, orient, y0 + 0.5, y1 + 0.5, std::max(std::abs(x0 + 0.5), std::abs(x1 + 0.5)), spans, slack);
    for (int y = y0; y <= y1; ++y) {
        const double py = y + 0.5;
        double lo = -INFINITY, hi = INFINITY;
        rowSpan(spans, py, lo, hi);
        const int xa = lo <= hi ? std::max(x0, int(std::ceil(std::max(lo, x0 - 1.0) - 0.5))) : x1 + 1;
        const int xb = lo <= hi ? std::min(x1, int(std::floor(std::min(hi, x1 + 1.0) - 0.5))) : x0 - 1;
        tally.spanned += std::max(0, xb - xa + 1);
        for (int x = x0; x <= x1; ++x) {
            if (!insidePolygon(sx, sy, m, orient, x + 0.5, py)) continue;
            ++tally.accepted;
            if (x < xa || x > xb) ++tally.dropped;
        }
    }
}

/// 4,000 triangles and quads at pixel scale around @p offset: corners on pixel centres (edges
/// through centres, the test's value exactly 0), near-horizontal and near-vertical edges, and
/// slivers.
SpanTally checkRandomPolygons(double offset, double slack) {
    std::mt19937 rng(23);
    std::uniform_real_distribution<double> coord(-20.0, 20.0), tiny(-1e-7, 1e-7);
    std::uniform_int_distribution<int> pixel(-20, 20);
    SpanTally tally;
    for (int trial = 0; trial < 4000; ++trial) {
        double sx[4], sy[4];
        const int m = trial % 2 ? 4 : 3;
        for (int i = 0; i < m; ++i) sx[i] = coord(rng), sy[i] = coord(rng);
        switch (trial % 10 / 2) {
            case 1:  // corners on pixel centres
                for (int i = 0; i < m; ++i) sx[i] = pixel(rng) + 0.5, sy[i] = pixel(rng) + 0.5;
                break;
            case 2:  // a near-horizontal edge
                sx[1] = sx[0] + 17.0, sy[1] = sy[0] + tiny(rng);
                break;
            case 3:  // a near-vertical edge
                sx[1] = sx[0] + tiny(rng), sy[1] = sy[0] + 17.0;
                break;
            case 4:  // a sliver
                sx[2] = sx[0] + (sx[1] - sx[0]) * 0.37 + tiny(rng), sy[2] = sy[0] + (sy[1] - sy[0]) * 0.37 + tiny(rng);
                break;
            default:
                break;
        }
        if (m == 4) {  // a convex quad: the corners sorted by angle around their centre
            const double cx = (sx[0] + sx[1] + sx[2] + sx[3]) / 4, cy = (sy[0] + sy[1] + sy[2] + sy[3]) / 4;
            int order[4] = {0, 1, 2, 3};
            std::sort(order, order + 4, [&](int a, int b) { return std::atan2(sy[a] - cy, sx[a] - cx) < std::atan2(sy[b] - cy, sx[b] - cx); });
            double qx[4], qy[4];
            for (int i = 0; i < 4; ++i) qx[i] = sx[order[i]], qy[i] = sy[order[i]];
            std::copy(qx, qx + 4, sx), std::copy(qy, qy + 4, sy);
        }
        for (int i = 0; i < m; ++i) sx[i] += offset, sy[i] += offset;
        checkPolygon(sx, sy, m, slack, tally);
    }
    return tally;
}

}  // namespace

TEST_CASE("a camera row span drops no pixel centre that the pixel test accepts", "[receivers][camera]") {
    // Near the image's origin and far out (a polygon clipped at the near plane reaches far past
    // the image; the rasterizer uses spans up to 1e9 pixels).
    for (const double offset : {0.0, 4096.0, 3.0e6}) {
        const SpanTally tally = checkRandomPolygons(offset, 0.01);
        INFO("offset " << offset << ": accepted " << tally.accepted << ", in spans " << tally.spanned);
        CHECK(tally.dropped == 0);
        CHECK(tally.accepted > 100000);
        // Tight: the spans hold few centres that the test then rejects.
        CHECK(tally.spanned < tally.accepted + tally.accepted / 20);
    }
}

TEST_CASE("the camera span check catches a span narrowed by a third of a pixel", "[receivers][camera]") {
    // The test above has teeth: without its rounding bound and slack, a span loses centres.
    CHECK(checkRandomPolygons(0.0, -0.3).dropped > 0);
}
