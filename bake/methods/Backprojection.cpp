#include "bake/methods/Backprojection.h"

#include "stream/util/TexelIndex.h"

#include <glm/geometric.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>

#if defined(__SSE4_1__)
#include <smmintrin.h>
#endif

namespace penumbra {
namespace {

constexpr int kSearchRadius = 2;  ///< texels each side read by the nearest-blocker search that sizes the region

/// The convex hull of @p points, counter-clockwise (Andrew's monotone chain).
std::vector<glm::dvec2> convexHull(std::vector<glm::dvec2> points) {
    std::sort(points.begin(), points.end(), [](const glm::dvec2& a, const glm::dvec2& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
    auto cross = [](const glm::dvec2& o, const glm::dvec2& a, const glm::dvec2& b) {
        return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    };
    std::vector<glm::dvec2> hull(2 * points.size());
    size_t k = 0;
    for (size_t i = 0; i < points.size(); ++i) {  // lower chain
        while (k >= 2 && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
        hull[k++] = points[i];
    }
    for (size_t i = points.size(), lower = k + 1; i-- > 1;) {  // upper chain
        while (k >= lower && cross(hull[k - 2], hull[k - 1], points[i - 1]) <= 0) --k;
        hull[k++] = points[i - 1];
    }
    hull.resize(k > 1 ? k - 1 : k);
    return hull;
}

using Transmission = std::array<float, LightGrid::kCells * LightGrid::kCells>;
static_assert(LightGrid::kCells * LightGrid::kCells % 8 == 0, "visibleFraction() sums in eight lanes");

}  // namespace

DepthPyramid::DepthPyramid(const DepthMap& shadow, int layer) : shadow_(&shadow), layer_(layer) {
    int fine = shadow.res;
    while (fine > 1) {
        const int coarse = (fine + 1) / 2;
        Planes level;
        level.nearest.resize(size_t(coarse) * coarse), level.quantile.resize(size_t(coarse) * coarse);
        const int l = levels();
        // Rows in parallel: each texel depends only on the finer level, so the result does not
        // depend on the split (level 1 of four 1024² layers took 60 ms on one thread).
        tbb::parallel_for(tbb::blocked_range<int>(0, coarse, 16), [&](const tbb::blocked_range<int>& rows) {
            for (int y = rows.begin(); y < rows.end(); ++y) {
                const size_t row = size_t(y) * coarse;
                const int done = l == 1 ? firstLevelRow(fine, y, level, row) : 0;
                for (int x = done; x < coarse; ++x) level.set(row + size_t(x), coarseTexel(l, fine, x, y));
            }
        });
        res_.push_back(coarse);
        levels_.push_back(std::move(level));
        fine = coarse;
    }
}

int DepthPyramid::firstLevelRow(int fine, int y, Planes& level, size_t first) const {
#if defined(__SSE4_1__)
    // coarseTexel()'s level 1, four texels at a time: the same minima and compare-exchanges, lane
    // by lane (std::min(a, b) is minps(b, a), std::max(a, b) is maxps(b, a), NaN included), so
    // the same bits. Only texels whose four fine texels are all inside the map.
    if (2 * y + 1 >= fine) return 0;
    const float* top = &shadow_->depth[(size_t(layer_) * shadow_->res + size_t(2 * y)) * shadow_->res];
    const float* bottom = top + shadow_->res;
    int x = 0;
    for (; 2 * x + 7 < fine; x += 4) {
        const __m128 t0 = _mm_loadu_ps(top + 2 * x), t1 = _mm_loadu_ps(top + 2 * x + 4);
        const __m128 b0 = _mm_loadu_ps(bottom + 2 * x), b1 = _mm_loadu_ps(bottom + 2 * x + 4);
        __m128 d[4] = {_mm_shuffle_ps(t0, t1, _MM_SHUFFLE(2, 0, 2, 0)), _mm_shuffle_ps(t0, t1, _MM_SHUFFLE(3, 1, 3, 1)),
                       _mm_shuffle_ps(b0, b1, _MM_SHUFFLE(2, 0, 2, 0)), _mm_shuffle_ps(b0, b1, _MM_SHUFFLE(3, 1, 3, 1))};
        __m128 nearest = _mm_set1_ps(INFINITY);
        for (const __m128& v : d) nearest = _mm_min_ps(v, nearest);
        auto order = [&](int a, int b) {
            const __m128 lo = _mm_min_ps(d[b], d[a]), hi = _mm_max_ps(d[b], d[a]);
            d[a] = lo, d[b] = hi;
        };
        order(0, 1), order(2, 3), order(0, 2), order(1, 3), order(1, 2);
        alignas(16) float n[4], q[4][4];
        _mm_store_ps(n, nearest);
        for (int k = 0; k < 4; ++k) _mm_store_ps(q[k], d[k]);
        for (int i = 0; i < 4; ++i) level.set(first + size_t(x + i), Texel{n[i], {q[0][i], q[1][i], q[2][i], q[3][i]}});
    }
    return x;
#else
    (void)fine, (void)y, (void)level, (void)first;
    return 0;
#endif
}

DepthPyramid::Texel DepthPyramid::coarseTexel(int l, int fine, int x, int y) const {
    Texel t;
    t.nearest = INFINITY;
    if (l == 1) {
        // Level 0's quantiles are its depth four times, so the sixteen values sorted are the four
        // depths sorted, each four times, and the quantiles (the 3rd, 7th, 11th and 15th) are
        // the four depths in order: the same result as the general case for a quarter of the sort.
        std::array<float, 4> depth;
        for (int c = 0; c < 4; ++c) {
            const int cx = 2 * x + c % 2, cy = 2 * y + c / 2;
            depth[size_t(c)] = cx < fine && cy < fine ? shadow_->at(cx, cy, layer_) : INFINITY;
            t.nearest = std::min(t.nearest, depth[size_t(c)]);
        }
        // Sorted by a network of five compare-exchanges (level 1 is three quarters of the
        // pyramid's texels, and std::sort's call cost more than the sort).
        auto order = [&](size_t a, size_t b) {
            const float lo = std::min(depth[a], depth[b]), hi = std::max(depth[a], depth[b]);
            depth[a] = lo, depth[b] = hi;
        };
        order(0, 1), order(2, 3), order(0, 2), order(1, 3), order(1, 2);
        t.quantile = depth;
        return t;
    }
    // Four quantiles of the children's sixteen (a fine texel counts four times).
    std::array<float, 4 * kQuantiles> all;
    for (int c = 0; c < 4; ++c) {
        const int cx = 2 * x + c % 2, cy = 2 * y + c / 2;
        const Texel child = cx < fine && cy < fine ? at(l - 1, cx, cy) : Texel{INFINITY, {INFINITY, INFINITY, INFINITY, INFINITY}};
        t.nearest = std::min(t.nearest, child.nearest);
        std::copy(child.quantile.begin(), child.quantile.end(), all.begin() + c * kQuantiles);
    }
    // The children's quantiles are each ascending: merged, not sorted (the same order, in about
    // half the comparisons of a sort of sixteen, most of the pyramids' build).
    std::array<float, 2 * kQuantiles> low, high;
    std::merge(all.begin(), all.begin() + 4, all.begin() + 4, all.begin() + 8, low.begin());
    std::merge(all.begin() + 8, all.begin() + 12, all.begin() + 12, all.end(), high.begin());
    std::merge(low.begin(), low.end(), high.begin(), high.end(), all.begin());
    for (int q = 0; q < kQuantiles; ++q) t.quantile[size_t(q)] = all[size_t(4 * q + 2)];
    return t;
}

DepthPyramid::Texel DepthPyramid::at(int level, int x, int y) const {
    if (level > 0) return this->level(level).texel(x, y);
    const float z = shadow_->at(x, y, layer_);
    return {z, {z, z, z, z}};
}

DepthPyramid::Level DepthPyramid::level(int l) const {
    if (l > 0) return {levels_[size_t(l - 1)].nearest.data(), levels_[size_t(l - 1)].quantile.data(), nullptr, res_[size_t(l - 1)]};
    return {nullptr, nullptr, &shadow_->depth[size_t(layer_) * shadow_->res * shadow_->res], shadow_->res};
}

float DepthPyramid::nearest() const { return levels_.empty() ? at(0, 0, 0).nearest : levels_.back().nearest[0]; }

float DepthPyramid::nearestIn(int level, glm::dvec2 lo, glm::dvec2 hi) const {
    const auto [x0, x1, y0, y1] = texelsOver(level, lo, hi);
    // The plane of nearest depths (at() per texel cost a fifth of the lookup's search).
    const Level texels = this->level(level);
    const float* plane = texels.nearestPlane();
    float z = INFINITY;
    for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) z = std::min(z, plane[size_t(y) * texels.res + x]);
    return z;
}

uint64_t DepthPyramid::plannedBytes(int resolution) {
    uint64_t bytes = 0;
    for (uint64_t r = (uint64_t(resolution) + 1) / 2; r >= 1; r = (r + 1) / 2) {
        bytes += r * r * sizeof(Texel);
        if (r == 1) break;
    }
    return bytes;
}

LightGrid::LightGrid(const std::vector<glm::dvec2>& outline) {
    const std::vector<glm::dvec2> hull = convexHull(outline);
    glm::dvec2 hi(-INFINITY);
    lo = glm::dvec2(INFINITY);
    for (const glm::dvec2& p : hull) lo = glm::min(lo, p), hi = glm::max(hi, p), radius = std::max(radius, glm::length(p));
    if (hull.size() < 3 || !(hi.x - lo.x > 1e-12 * radius) || !(hi.y - lo.y > 1e-12 * radius)) return;  // no area
    cell = (hi - lo) / double(kCells);
    for (int j = 0; j < kCells; ++j)
        for (int i = 0; i < kCells; ++i) {
            const glm::dvec2 q = lo + (glm::dvec2(i, j) + 0.5) * cell;
            bool in = true;
            for (size_t e = 0; e < hull.size() && in; ++e) {
                const glm::dvec2 &a = hull[e], &b = hull[(e + 1) % hull.size()];
                in = (b.x - a.x) * (q.y - a.y) - (b.y - a.y) * (q.x - a.x) >= 0;
            }
            if (in) inside_.push_back(uint16_t(j * kCells + i));
        }
    for (const uint16_t c : inside_) openRows_[c / kCells] = uint16_t(openRows_[c / kCells] | 1u << (c % kCells));
}

namespace {

/// Multiplies the cells of columns [@p i0, @p i1) in rows [@p j0, @p j1) by @p keep, and returns
/// how many of them it closes (were not 0, and @p keep is 0). A row of twelve cells is three
/// 4-lane products with the columns outside [i0, i1) multiplied by 1 (exactly themselves), in
/// place of two loops with bounds that change from texel to texel (5-7 % of a lookup's time on
/// FLOWERS and SPONZA-LIKE). The same bits as the loops.
int scaleCells(std::array<float, LightGrid::kCells * LightGrid::kCells>& cells, int i0, int i1, int j0, int j1, float keep) {
    constexpr int n = LightGrid::kCells;
#if defined(__SSE4_1__)
    static_assert(n == 12, "three 4-lane vectors per row");
    const __m128i first = _mm_set1_epi32(i0 - 1), end = _mm_set1_epi32(i1);
    __m128 in[3];
    for (int v = 0; v < 3; ++v) {
        const __m128i column = _mm_setr_epi32(4 * v, 4 * v + 1, 4 * v + 2, 4 * v + 3);
        in[v] = _mm_castsi128_ps(_mm_and_si128(_mm_cmpgt_epi32(column, first), _mm_cmpgt_epi32(end, column)));
    }
    if (keep == 0.0f) {
        int closed = 0;
        for (int j = j0; j < j1; ++j)
            for (int v = 0; v < 3; ++v) {
                float* at = &cells[size_t(j * n + 4 * v)];
                const __m128 t = _mm_loadu_ps(at);
                closed += __builtin_popcount(unsigned(_mm_movemask_ps(_mm_and_ps(in[v], _mm_cmpneq_ps(t, _mm_setzero_ps())))));
                _mm_storeu_ps(at, _mm_andnot_ps(in[v], t));
            }
        return closed;
    }
    __m128 factor[3];
    for (int v = 0; v < 3; ++v) factor[v] = _mm_blendv_ps(_mm_set1_ps(1.0f), _mm_set1_ps(keep), in[v]);
    for (int j = j0; j < j1; ++j)
        for (int v = 0; v < 3; ++v) {
            float* at = &cells[size_t(j * n + 4 * v)];
            _mm_storeu_ps(at, _mm_mul_ps(_mm_loadu_ps(at), factor[v]));
        }
    return 0;
#else
    int closed = 0;
    for (int j = j0; j < j1; ++j)
        for (int i = i0; i < i1; ++i) {
            float& t = cells[size_t(j * n + i)];
            closed += keep == 0.0f && t != 0.0f;
            t *= keep;
        }
    return closed;
#endif
}

/// One receiver's backprojection in @p view: the receiver's depth and image position, and the
/// transformation from a blocker's depth to the scale k of its footprint on the light. Everything
/// that depends only on the receiver is computed once here, so a texel costs a few products and
/// one division (per-texel work is most of a lookup).
struct Backprojector {
    const LightView& view;
    const LightGrid& grid;
    ViewPoint p;
    glm::dvec3 r, n;  ///< the receiver and its normal towards the light's centre (zero: none)
    double bias, eps;
    /// Leaves the cells unset (an aggregate's braces would zero them for every lookup).
    Backprojector(const LightView& v, const LightGrid& g, const glm::dvec3& receiver, double depthBias, double epsilon)
        : view(v), grid(g), p(v.project(receiver)), r(receiver), n(0.0), bias(depthBias), eps(epsilon) {}
    /// The cells' state, valid once touched: most lookups block no cell, and the copy of the open
    /// grid and the sum over it were a tenth of the lookup's instructions. While every cell is
    /// open (1) or closed (0), as it is at level 0 (whose texels hide all or nothing), the state
    /// is a bit per cell (openRows); the first partial hide turns it into transmissions, fractional.
    std::array<uint16_t, LightGrid::kCells> openRows;
    Transmission transmitted;
    bool touched = false, fractional = false;
    /// Once touched, at least the number of cells inside the outline still open (exactly, while
    /// not fractional): a cell leaves only when something sets it to 0, so none is left when this
    /// reaches 0, and the receiver's remaining texels cannot change its result (0) any more.
    int openCells = 0;
    void touch() {
        if (!touched) openRows = grid.openRows(), touched = true, openCells = int(grid.insideCells().size());
    }
    /// The cells as transmissions (an open cell's is exactly 1, a closed one's 0).
    Transmission& cells() {
        touch();
        if (!fractional) {
            for (int j = 0; j < LightGrid::kCells; ++j)
                for (int i = 0; i < LightGrid::kCells; ++i) transmitted[size_t(j * LightGrid::kCells + i)] = openRows[size_t(j)] >> i & 1 ? 1.0f : 0.0f;
            fractional = true;
        }
        return transmitted;
    }
    /// Closes the cells of columns [@p i0, @p i1) in rows [@p j0, @p j1).
    void close(int i0, int i1, int j0, int j1) {
        if (fractional) {
            openCells -= scaleCells(transmitted, i0, i1, j0, j1, 0.0f);
            return;
        }
        touch();
        const unsigned columns = (1u << i1) - (1u << i0);
        for (int j = j0; j < j1; ++j) {
            openCells -= __builtin_popcount(openRows[size_t(j)] & columns);
            openRows[size_t(j)] = uint16_t(openRows[size_t(j)] & ~columns);
        }
    }
    bool umbra() const { return touched && openCells == 0; }
    // Set by prepare(): the texel's size, 1/z_r, the cells' reciprocal sizes, and the plane
    // distance of the point at depth q on a texel's central ray as base + q * along, with base
    // and along linear in the texel's image position.
    double texel = 0, inverseZ = 0;
    glm::dvec2 inverseCell{0.0};
    bool hasPlane = false;
    double base0 = 0, along0 = 0, perX = 0, perY = 0;
    // Set by readLevel(): the level's texel size s (in fine texels), half a texel in image units,
    // and the in-front margin of a quantile at depth q, fixedMargin + marginSlope q.
    double s = 1, halfTexel = 0, fixedMargin = 0, marginSlope = 0;

    void prepare() {
        texel = view.texel(), inverseZ = 1.0 / p.z, inverseCell = 1.0 / grid.cell;
        hasPlane = glm::dot(n, n) > 0;
        // Perspective: the point is origin + q (axis + lateral); orthographic: origin + lateral + q axis.
        base0 = glm::dot(view.origin - r, n), along0 = glm::dot(view.axis, n);
        perX = glm::dot(view.e1, n), perY = glm::dot(view.e2, n);
    }
    void readLevel(int level) {
        s = double(1 << level), halfTexel = 0.5 * s * texel;
        // A quantile's depth is within 0.71 s texels of a surface point.
        const double marginPerDepth = (bias + 0.71 * s) * texel;
        fixedMargin = eps + (view.ortho ? marginPerDepth : 0.0), marginSlope = view.ortho ? 0.0 : marginPerDepth;
    }
    /// Blocks the cells whose light points lie behind the receiver's plane (normal n, set before
    /// it faces the centre); the distance from the plane is linear across the light, so the
    /// corners decide at once, and the cells are touched only when some of the light is behind.
    void blockBehindPlane() {
        // A light point at image offset l lies at depth l . depthSlope along the axis.
        const double along = glm::dot(view.axis, n);
        const double c0 = glm::dot(view.ortho ? -view.axis : view.origin - r, n), cx = glm::dot(view.e1, n) + grid.depthSlope.x * along,
                     cy = glm::dot(view.e2, n) + grid.depthSlope.y * along;
        const glm::dvec2 hi = grid.hi();
        if (c0 + std::min(grid.lo.x * cx, hi.x * cx) + std::min(grid.lo.y * cy, hi.y * cy) >= 0) return;  // all in front
        // The same sums as c0 + l.x cx + l.y cy at each cell centre l, with the column part shared.
        touch();  // the first change to the cells: still one bit each
        std::array<double, LightGrid::kCells> column;
        for (int i = 0; i < LightGrid::kCells; ++i) column[size_t(i)] = c0 + (grid.lo.x + (i + 0.5) * grid.cell.x) * cx;
        openCells = 0;
        for (int j = 0; j < LightGrid::kCells; ++j) {
            const double row = (grid.lo.y + (j + 0.5) * grid.cell.y) * cy;
            unsigned behind = 0;
            for (int i = 0; i < LightGrid::kCells; ++i) behind |= unsigned(column[size_t(i)] + row < 0) << i;
            openRows[size_t(j)] = uint16_t(openRows[size_t(j)] & ~behind);
            openCells += __builtin_popcount(openRows[size_t(j)]);
        }
    }

    /// The image box (fine texels) that can hold blockers at depth @p z or farther over the light:
    /// the outline's box scaled by k(z) around the receiver, within the square of radiusFor(z).
    void searchBox(double z, glm::dvec2& lo, glm::dvec2& hi) const {
        const double radius = radiusFor(z), perLight = std::max(0.0, kOf(z)) / texel;  // fine texels per light unit
        const glm::dvec2 at(p.x, p.y);
        lo = glm::max(at - radius, at + perLight * grid.lo), hi = glm::min(at + radius, at + perLight * grid.hi());
    }
    /// Where the segment to the light meets depth @p z: image offset per unit of light offset.
    double kOf(double z) const { return view.ortho ? p.z - z : 1.0 / z - inverseZ; }
    /// The search radius in fine texels for blockers as near as depth @p z.
    double radiusFor(double z) const { return std::clamp(grid.radius * kOf(z) / texel, 0.0, double(view.res)); }

    /// The cells [@p i0, @p i1) x [@p j0, @p j1) whose centres lie in the box [@p a, @p b] of the
    /// light (firstCellX/Y of its corners); false when there are none. The two axes in one SSE4.1
    /// register each: the same operations as firstCellX/Y lane by lane, so the same bits (NaN and
    /// out-of-range values are clamped in double first, as clampedTexel does).
    bool cellBox(const glm::dvec2& a, const glm::dvec2& b, int& i0, int& i1, int& j0, int& j1) const {
#if defined(__SSE4_1__)
        const __m128d lo = _mm_setr_pd(grid.lo.x, grid.lo.y), inverse = _mm_setr_pd(inverseCell.x, inverseCell.y);
        const __m128d halfCell = _mm_set1_pd(0.5), zero = _mm_setzero_pd(), cells = _mm_set1_pd(LightGrid::kCells);
        auto first = [&](const glm::dvec2& v) {
            const __m128d c = _mm_round_pd(_mm_sub_pd(_mm_mul_pd(_mm_sub_pd(_mm_setr_pd(v.x, v.y), lo), inverse), halfCell), _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC);
            return _mm_cvttpd_epi32(_mm_min_pd(_mm_max_pd(c, zero), cells));  // maxpd gives 0 for NaN
        };
        const __m128i from = first(a), to = first(b);
        i0 = _mm_cvtsi128_si32(from), j0 = _mm_extract_epi32(from, 1), i1 = _mm_cvtsi128_si32(to), j1 = _mm_extract_epi32(to, 1);
        return (_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(to, from))) & 3) == 3;
#else
        i0 = firstCellX(a.x), i1 = firstCellX(b.x), j0 = firstCellY(a.y), j1 = firstCellY(b.y);
        return i0 < i1 && j0 < j1;
#endif
    }
    /// The first index of a cell whose centre is at or past @p value (light units), along x or y.
    int firstCellX(double value) const { return clampedTexel(std::ceil((value - grid.lo.x) * inverseCell.x - 0.5), 0, LightGrid::kCells); }
    int firstCellY(double value) const { return clampedTexel(std::ceil((value - grid.lo.y) * inverseCell.y - 0.5), 0, LightGrid::kCells); }

    /// A texel's centre (fine texels) and its front test: depth q is in front when c0 + q c1 > 0,
    /// beyond the receiver's plane by the margin (or, without a plane, nearer than the receiver by
    /// it). Linear in q, so with c1 <= 0 (the usual case: depth runs towards the plane) the
    /// quantiles in front are a prefix of the ascending four, and the first one out ends the
    /// texel (most texels around a receiver are its own surface and end at once).
    struct FrontTest {
        glm::dvec2 centre;
        double c0, c1;
    };
    FrontTest frontTest(int tx, int ty) const {
        const glm::dvec2 centre((tx + 0.5) * s, (ty + 0.5) * s);
        const glm::dvec2 image = centre * texel - view.halfExtent;  // tangent (perspective) or world units
        const double lateral = image.x * perX + image.y * perY;
        const double base = view.ortho ? base0 + lateral : base0, along = view.ortho ? along0 : along0 + lateral;
        return {centre, hasPlane ? base - fixedMargin : p.z - fixedMargin, hasPlane ? along - marginSlope : -(1.0 + marginSlope)};
    }
    /// Hides the light behind a texel of the level set by readLevel() (front test @p f), for the share
    /// of its quantiles that lie in front of the receiver's plane.
    /// @return true when no layer behind this one can hide anything either: none of its
    /// quantiles is in front, and c1 <= 0, so the deeper layers' quantiles (each at least this
    /// layer's: the order statistics of depths that are each at least this layer's) are not.
    bool addTexel(const DepthPyramid::Texel& t, const FrontTest& f) {
        int blocking = 0;
        double depthSum = 0;
        for (const float q : t.quantile) {
            if (!(q < p.z)) break;
            if (f.c0 + q * f.c1 > 0) ++blocking, depthSum += q;
            else if (f.c1 <= 0) break;
        }
        if (blocking == 0) return f.c1 <= 0;
        static constexpr double kInverseCount[] = {0.0, 1.0, 1.0 / 2, 1.0 / 3, 1.0 / 4};
        hide(f.centre, blocking, depthSum * kInverseCount[blocking]);
        return false;
    }
    /// addTexel() for a level-0 texel at depth @p z < p.z (the caller's test): its four quantiles
    /// are z, so all of them are in front or none, and their mean is z exactly (for a float z,
    /// z + z + z + z and its quarter are exact in double). Two thirds of FLOWERS' texels are read
    /// at level 0, and the Texel copy and the quantile loop were a tenth of the lookups' time.
    /// @return as addTexel(): true when z is not in front and c1 <= 0, so that no deeper layer
    /// is (c0 + q c1 only falls as q grows, and so do its rounded values). Around a receiver most
    /// texels are its own surface, whose next layer this saves reading.
    bool addDepth(float z, const FrontTest& f) {
        if (!(f.c0 + z * f.c1 > 0)) return f.c1 <= 0;
        hide(f.centre, DepthPyramid::kQuantiles, double(z));
        return false;
    }

    /// Hides the light behind the texel at @p centre for @p blocking of its quantiles, in front
    /// at mean depth @p z.
    void hide(const glm::dvec2& centre, int blocking, double z) {
        // 1/k at the quantiles' mean depth z: 1 / (z_r - z) (orthographic) or z z_r / (z_r - z)
        // (perspective, k = 1/z - 1/z_r), one division where the plain form takes three.
        const double gap = p.z - z;
        if (!(gap > 0)) return;
        const double inverseK = view.ortho ? 1.0 / gap : z * p.z / gap;
        const glm::dvec2 offset = (centre - glm::dvec2(p.x, p.y)) * texel, half(halfTexel);
        const glm::dvec2 a = (offset - half) * inverseK, b = (offset + half) * inverseK;
        int i0, i1, j0, j1;
        if (!cellBox(a, b, i0, i1, j0, j1)) return;
        // Neighbouring texels at one depth share box edges, so each cell is counted once.
        if (blocking == DepthPyramid::kQuantiles) return close(i0, i1, j0, j1);
        const float keep = float(1.0 - double(blocking) / DepthPyramid::kQuantiles);
        cells();
        openCells -= scaleCells(transmitted, i0, i1, j0, j1, keep);
    }

    /// The mean transmission of the cells inside the outline (the others are held at 0), summed
    /// in eight independent lanes: one chain of 144 dependent additions cost more than a
    /// receiver's texels in the profile.
    float visibleFraction() const {
        if (!touched) return 1.0f;  // every inside cell open: the sum below gives exactly 1 too
        // Bits: openCells, exact while every change closed whole cells, is the count that the sum
        // of their transmissions (each exactly 1) gives.
        if (!fractional) return float(double(openCells) / double(grid.insideCells().size()));
        std::array<float, 8> lane{};
        for (size_t c = 0; c < transmitted.size(); c += lane.size())
            for (size_t l = 0; l < lane.size(); ++l) lane[l] += transmitted[c + l];
        const double sum = ((double(lane[0]) + lane[1]) + (double(lane[2]) + lane[3])) + ((double(lane[4]) + lane[5]) + (double(lane[6]) + lane[7]));
        return float(sum / double(grid.insideCells().size()));
    }
};

}  // namespace

float backprojectedVisibility(const LightView& view, std::span<const DepthPyramid> pyramids, const LightGrid& grid,
                              const glm::dvec3& r, const glm::dvec3& normal, double bias, double eps, int taps) {
    Backprojector b(view, grid, r, bias, eps);
    if (glm::length(normal) > 0) {
        // Surfaces are taken as the sides of solids, as the exact rule finds them for closed
        // meshes: the light behind the receiver's own plane is blocked by the solid. (For an open
        // surface that light would reach it from behind, where it carries no irradiance.)
        b.n = glm::normalize(normal);
        b.blockBehindPlane();
        if (b.umbra()) return 0.0f;
        if (glm::dot(b.n, view.ortho ? -view.axis : view.origin - r) < 0) b.n = -b.n;  // the side facing the centre
    }
    b.prepare();
    const DepthPyramid& nearestLayer = pyramids[0];
    auto levelFor = [&](double radius, int taps) {
        int level = 0;
        while (level + 1 < nearestLayer.levels() && radius > taps * double(1 << level)) ++level;
        return level;
    };
    // Only texels over the light's outline scaled by k can hide a cell, and k is largest for the
    // nearest blocker: the outline's box, t_r + k [lo, hi], within the square of the radius (a
    // square light's box is half the square around its circumscribed circle). Texels beside it
    // hide no cell centre. The search sizes that box by the nearest blocker around, twice refined.
    glm::dvec2 lo, hi;
    double nearest = nearestLayer.nearest();
    for (int pass = 0; pass < 2 && nearest < b.p.z; ++pass) {
        b.searchBox(nearest, lo, hi);
        nearest = std::max(nearest, double(nearestLayer.nearestIn(levelFor(b.radiusFor(nearest), kSearchRadius), lo, hi)));
    }
    if (!(nearest < b.p.z)) return b.visibleFraction();
    const int level = levelFor(b.radiusFor(nearest), taps);
    b.readLevel(level);
    b.searchBox(nearest, lo, hi);
    const DepthPyramid::TexelRange range = nearestLayer.texelsOver(level, lo, hi);
    const int x0 = range.x0, x1 = range.x1, y0 = range.y0, y1 = range.y1;
    std::array<DepthPyramid::Level, 8> layers;  // DepthMap's layers: a few
    const size_t layerCount = std::min(pyramids.size(), layers.size());
    for (size_t l = 0; l < layerCount; ++l) layers[l] = pyramids[l].level(level);
    // One texel's layers, nearest first, from its front test @p f; true once the cells are all
    // closed (the umbra): visibleFraction() would sum zeros, and the texels left could only
    // multiply them. With the exit above for receivers that face away from the whole light, a
    // quarter of SPONZA-LIKE's lookups end early.
    auto visit = [&](int tx, int ty, const Backprojector::FrontTest& f) {
        for (size_t l = 0; l < layerCount; ++l) {
            bool deeperHideNothing;
            if (level == 0) {
                const float z = layers[l].depthAt(tx, ty);
                if (!(z < b.p.z)) break;  // nor any layer behind
                deeperHideNothing = b.addDepth(z, f);
            } else {
                const DepthPyramid::Texel t = layers[l].texel(tx, ty);
                if (!(t.nearest < b.p.z)) break;
                deeperHideNothing = b.addTexel(t, f);
            }
            if (b.umbra()) return true;
            if (deeperHideNothing) break;
        }
        return false;
    };
    constexpr int kRow = 64;
    if (level == 0 && x1 - x0 < kRow) {
        // Level 0 (most lookups), a row at a time: which texels need their layers is decided for
        // the whole row without a branch, and only those are visited; most texels around a
        // receiver need none, and the branches per texel were most of the loop's time. A texel
        // needs them when its first layer's depth z is nearer than the receiver and in front, or
        // not in front with c1 > 0: otherwise visit() changes nothing (every deeper layer's depth
        // is at least z). Coarser levels read fewer, larger texels, and this measured no gain there.
        std::array<Backprojector::FrontTest, kRow> tests;
        for (int ty = y0; ty <= y1; ++ty) {
            uint64_t needed = 0;
            for (int tx = x0; tx <= x1; ++tx) {
                const Backprojector::FrontTest& f = tests[size_t(tx - x0)] = b.frontTest(tx, ty);
                const float z = layers[0].depthAt(tx, ty);
                const bool near = z < b.p.z, front = f.c0 + z * f.c1 > 0, deeper = f.c1 > 0;
                needed |= uint64_t(near & (front | deeper)) << (tx - x0);
            }
            for (; needed; needed &= needed - 1) {
                const int i = std::countr_zero(needed);
                if (visit(x0 + i, ty, tests[size_t(i)])) return 0.0f;
            }
        }
        return b.visibleFraction();
    }
    for (int ty = y0; ty <= y1; ++ty)
        for (int tx = x0; tx <= x1; ++tx) {
            // The layers are nearest first: none is in front of the receiver unless the first is.
            if (!(layers[0].nearestAt(tx, ty) < b.p.z)) continue;
            if (visit(tx, ty, b.frontTest(tx, ty))) return 0.0f;  // one front test per texel, for all its layers
        }
    return b.visibleFraction();
}

}  // namespace penumbra
