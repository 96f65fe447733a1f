#include "receivers/AtlasPacking.h"

#include "stream/util/Progress.h"

#include <tbb/parallel_for.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <numeric>

namespace penumbra {
namespace {

constexpr int kTurns = 4;  ///< orientations tried: quarter turns
constexpr int kMaxBisections = 24;
constexpr double kDensityPrecision = 0.004;  ///< bisection stops when the bracket is this narrow (relative)

/// Half-open runs [first, second) of texels per row.
struct RowRuns {
    std::vector<uint32_t> start;  ///< rows + 1 offsets into runs
    std::vector<std::pair<int, int>> runs;
    int rows() const { return int(start.size()) - 1; }
};

/// A chart's texels at one density and orientation: the texels its triangles touch
/// (conservatively), and the same grown by the padding. Raw rows are 0 .. height-1; dilated
/// rows are -padding .. height+padding-1, stored from index 0; x may be negative there.
struct Mask {
    int width = 0, height = 0;
    RowRuns raw, dilated;
    /// Per dilated row: its longest run, which a free run of that atlas row must hold (a
    /// necessary condition, tested before the runs themselves).
    std::vector<int> widest;
    int widestRow = 0;         ///< the dilated row with the longest run (the first of them)
    int narrowest = 0;         ///< the shortest longest run of a dilated row
    bool contiguous = true;    ///< no empty dilated row between non-empty ones
    int firstRow = 0;          ///< the first non-empty dilated row
};

/// Points of polygon @p in with y in [y0, y1] (Sutherland-Hodgman on the two lines).
int clipToSlab(const glm::dvec2* in, int count, double y0, double y1, glm::dvec2* out) {
    glm::dvec2 buffer[8];
    const glm::dvec2* source = in;
    glm::dvec2* target = buffer;
    for (int side = 0; side < 2; ++side) {
        int n = 0;
        auto inside = [&](glm::dvec2 p) { return side == 0 ? p.y - y0 : y1 - p.y; };
        for (int i = 0; i < count; ++i) {
            const glm::dvec2 p = source[i], q = source[(i + 1) % count];
            const double dp = inside(p), dq = inside(q);
            if (dp >= 0) target[n++] = p;
            if ((dp >= 0) != (dq >= 0)) target[n++] = p + (q - p) * (dp / (dp - dq));
        }
        count = n;
        source = target;
        target = out;
    }
    return count;
}

/// Chart coordinates (world units) to texels inside the chart's mask, turned by @p turns quarter turns.
glm::dvec2 localTexel(const Chart& chart, int turns, double s, glm::dvec2 uv) {
    const glm::dvec2 p = uv * s, e = chart.size * s;
    glm::dvec2 q = p;
    if (turns == 1) q = glm::dvec2(e.y - p.y, p.x);
    else if (turns == 2) q = glm::dvec2(e.x - p.x, e.y - p.y);
    else if (turns == 3) q = glm::dvec2(p.y, e.x - p.x);
    return q + glm::dvec2(kMaskOffset);
}

/// A bitmap of rows x bits, set by ranges, read back as runs.
class RowBits {
public:
    RowBits(int rows, int bits) : words_((bits + 63) / 64), bits_(size_t(rows) * size_t(words_), 0) {}
    uint64_t* row(int y) { return bits_.data() + size_t(y) * words_; }
    void set(int y, int a, int b) {
        uint64_t* r = row(y);
        for (int x = a; x < b;) {
            const int w = x / 64, bit = x % 64, n = std::min(64 - bit, b - x);
            r[w] |= (n == 64 ? ~uint64_t(0) : ((uint64_t(1) << n) - 1)) << bit;
            x += n;
        }
    }
    void orRow(int target, RowBits& from, int source) {
        uint64_t *t = row(target), *s = from.row(source);
        for (int w = 0; w < words_; ++w) t[w] |= s[w];
    }
    /// Runs of row y, shifted by -offset.
    void runs(int y, int offset, RowRuns& out) {
        const uint64_t* r = row(y);
        int x = 0;
        const int end = words_ * 64;
        while (x < end) {
            while (x < end && !(r[x / 64] >> (x % 64) & 1)) x += (r[x / 64] >> (x % 64)) == 0 ? 64 - x % 64 : 1;
            if (x >= end) break;
            int b = x;
            while (b < end && (r[b / 64] >> (b % 64) & 1)) b += ~(r[b / 64] >> (b % 64)) == 0 ? 64 - b % 64 : 1;
            out.runs.emplace_back(x - offset, b - offset);
            x = b;
        }
        out.start.push_back(uint32_t(out.runs.size()));
    }

private:
    int words_;
    std::vector<uint64_t> bits_;
};

/// The per-row widths of @p mask's reservation that findInRows() tests first.
void measureRows(Mask& mask) {
    const RowRuns& d = mask.dilated;
    mask.widest.assign(size_t(d.rows()), 0);
    int first = -1, last = -1;
    for (int k = 0; k < d.rows(); ++k) {
        for (uint32_t r = d.start[size_t(k)]; r < d.start[size_t(k) + 1]; ++r)
            mask.widest[size_t(k)] = std::max(mask.widest[size_t(k)], d.runs[r].second - d.runs[r].first);
        if (mask.widest[size_t(k)] == 0) continue;
        if (first < 0) first = k;
        last = k;
    }
    mask.narrowest = INT32_MAX;
    for (int k = std::max(first, 0); k <= last; ++k) {
        const int w = mask.widest[size_t(k)];
        if (w > mask.widest[size_t(mask.widestRow)]) mask.widestRow = k;
        if (w == 0) mask.contiguous = false;
        else mask.narrowest = std::min(mask.narrowest, w);
    }
    if (mask.narrowest == INT32_MAX) mask.narrowest = 0;
    mask.firstRow = std::max(first, 0);
}

Mask makeMask(const Chart& chart, double s, int turns, int padding) {
    Mask mask;
    const glm::dvec2 extent = (turns % 2 ? glm::dvec2(chart.size.y, chart.size.x) : chart.size) * s;
    mask.height = int(std::floor(extent.y + kMaskOffset + kMaskSlack)) + 1;
    const int width = int(std::floor(extent.x + kMaskOffset + kMaskSlack)) + 1;
    const int rows = mask.height + 2 * padding, bits = width + 2 * padding;
    RowBits raw(rows, bits);  // texel (x, y) is bit x + padding of row y + padding
    for (const auto& corner : chart.corners) {
        glm::dvec2 q[3];
        for (int k = 0; k < 3; ++k) q[k] = localTexel(chart, turns, s, chart.uv[corner[k]]);
        const double y0 = std::min({q[0].y, q[1].y, q[2].y}), y1 = std::max({q[0].y, q[1].y, q[2].y});
        const int j0 = std::max(0, int(std::floor(y0 - kMaskSlack)));
        const int j1 = std::min(mask.height - 1, int(std::floor(y1 + kMaskSlack)));
        for (int j = j0; j <= j1; ++j) {
            glm::dvec2 clipped[8];
            const int n = clipToSlab(q, 3, j - kMaskSlack, j + 1 + kMaskSlack, clipped);
            if (n == 0) continue;
            double x0 = INFINITY, x1 = -INFINITY;
            for (int i = 0; i < n; ++i) x0 = std::min(x0, clipped[i].x), x1 = std::max(x1, clipped[i].x);
            const int a = std::max(0, int(std::floor(x0 - kMaskSlack))), b = std::min(width, int(std::floor(x1 + kMaskSlack)) + 1);
            raw.set(j + padding, a + padding, b + padding);
            mask.width = std::max(mask.width, b);
        }
    }
    // Chebyshev dilation: each run widened by the padding, then rows ORed over the padding.
    RowBits wide(rows, bits), dilated(rows, bits);
    mask.raw.start.push_back(0);
    for (int j = 0; j < mask.height; ++j) {
        const size_t first = mask.raw.runs.size();
        raw.runs(j + padding, padding, mask.raw);
        for (size_t r = first; r < mask.raw.runs.size(); ++r)
            wide.set(j + padding, mask.raw.runs[r].first, mask.raw.runs[r].second + 2 * padding);
    }
    mask.dilated.start.push_back(0);
    for (int d = 0; d < rows; ++d) {
        for (int j = std::max(padding, d - padding); j <= std::min(rows - 1 - padding, d + padding); ++j) dilated.orRow(d, wide, j);
        dilated.runs(d, padding, mask.dilated);
    }
    measureRows(mask);
    return mask;
}

/// Occupied texels of the atlas, one bit each; rows are added as the packing grows upwards.
class Occupancy {
public:
    /// @param overhang how far a reservation may hang over the left and right borders (the padding)
    Occupancy(int width, int height, int overhang)
        : width_(width), height_(height), words_((width + 63) / 64), overhang_(overhang) {}
    int width() const { return width_; }
    int height() const { return height_; }
    /// First set bit in [a, b) of row y, or -1.
    int firstSet(int y, int a, int b) const {
        if (size_t(y) >= rows_.size()) return -1;
        const uint64_t* row = rows_[size_t(y)].data();
        for (int x = a; x < b;) {
            const int w = x / 64, bit = x % 64;
            uint64_t word = row[w] >> bit;
            if (b - x < 64 - bit) word &= (uint64_t(1) << (b - x)) - 1;
            if (word) return x + std::countr_zero(word);
            x += 64 - bit;
        }
        return -1;
    }
    /// First clear bit at or after x in row y (width when there is none).
    int firstClear(int y, int x) const {
        if (size_t(y) >= rows_.size()) return x;
        const uint64_t* row = rows_[size_t(y)].data();
        while (x < width_) {
            const int w = x / 64, bit = x % 64;
            const uint64_t word = ~row[w] >> bit;
            if (word) return std::min(width_, x + std::countr_zero(word));
            x += 64 - bit;
        }
        return width_;
    }
    /// The longest reservation run that row y can hold: its longest run of clear bits, counting
    /// the overhang beyond a border that the run touches (a reservation's run may hang over it).
    int longestFree(int y) const { return size_t(y) < longest_.size() ? longest_[size_t(y)] : width_ + 2 * overhang_; }
    void set(int y, int a, int b) {
        if (rows_.size() <= size_t(y)) {
            rows_.resize(size_t(y) + 1, std::vector<uint64_t>(size_t(words_), 0));
            longest_.resize(size_t(y) + 1, width_ + 2 * overhang_);
        }
        uint64_t* row = rows_[size_t(y)].data();
        for (int x = a; x < b;) {
            const int w = x / 64, bit = x % 64, n = std::min(64 - bit, b - x);
            row[w] |= (n == 64 ? ~uint64_t(0) : ((uint64_t(1) << n) - 1)) << bit;
            x += n;
        }
        int longest = 0;
        for (int x = firstClear(y, 0); x < width_;) {
            const int end = firstSet(y, x, width_);
            const int stop = end < 0 ? width_ : end;
            longest = std::max(longest, stop - x + (x == 0 ? overhang_ : 0) + (stop == width_ ? overhang_ : 0));
            x = stop < width_ ? firstClear(y, stop) : width_;
        }
        longest_[size_t(y)] = longest;
    }

private:
    int width_, height_, words_, overhang_;
    std::vector<std::vector<uint64_t>> rows_;
    std::vector<int> longest_;  ///< per row: longestFree()
};

/// The lowest, then leftmost position with its lower row in [@p yBegin, @p yEnd) where @p mask's
/// reservation is free and the mask inside the atlas; false when there is none.
bool findInRows(const Occupancy& occupied, const Mask& mask, int padding, int yBegin, int yEnd, int& px, int& py) {
    const int W = occupied.width();
    const int H = occupied.height();
    const RowRuns& d = mask.dilated;
    for (int y = yBegin; y < yEnd; ++y) {
        // Both tests below read the reservation's rows (dilated by the padding, so wider and more
        // of them than the mask's own), against atlas rows inside the atlas: rows outside it are
        // free. An atlas row too full for even the narrowest row rules out every position that
        // covers it: continue above the highest such row (in the filled part of the atlas this
        // steps a reservation's height at a time).
        auto atlasRow = [&](int k) { return y + k - padding; };
        int above = -1;
        for (int k = d.rows() - 1; k >= mask.firstRow && above < 0; --k)
            if (atlasRow(k) >= 0 && atlasRow(k) < H && occupied.longestFree(atlasRow(k)) < mask.narrowest) above = k;
        if (above >= 0) {
            if (mask.contiguous) y += above - mask.firstRow;  // the loop's ++y moves past it
            continue;
        }
        // Quick rejection: a row wider than the longest free run of its atlas row (the widest row
        // first: in a filling atlas it is the one that fails most often).
        auto fits = [&](int k) {
            return atlasRow(k) < 0 || atlasRow(k) >= H || occupied.longestFree(atlasRow(k)) >= mask.widest[size_t(k)];
        };
        bool room = fits(mask.widestRow);
        for (int k = 0; k < d.rows() && room; ++k) room = fits(k);
        if (!room) continue;
        int hint = 0;  // the row that blocked the last x: likely to block the next one too
        for (int x = 0; x + mask.width <= W;) {
            int next = -1;
            for (int k = 0; k < d.rows() && next < 0; ++k) {
                const int row = (hint + k) % d.rows(), atlasRow = y + row - padding;
                if (atlasRow < 0 || atlasRow >= H) continue;
                for (uint32_t r = d.start[size_t(row)]; r < d.start[size_t(row) + 1]; ++r) {
                    const auto [lo, hi] = d.runs[r];
                    const int q = occupied.firstSet(atlasRow, std::max(0, x + lo), std::min(W, x + hi));
                    if (q < 0) continue;
                    next = std::max(x + 1, occupied.firstClear(atlasRow, q) - lo);
                    hint = row;
                    break;
                }
            }
            if (next < 0) {
                px = x, py = y;
                return true;
            }
            x = next;
        }
    }
    return false;
}

/// Rows per task of the position search, and tasks per wave.
constexpr int kSearchRows = 16, kSearchBlocks = 8;

/// The lowest (at most @p yLimit), then leftmost position where @p mask's reservation is free
/// and the mask inside the atlas; false when there is none.
///
/// Blocks of rows are searched in parallel, a wave of them at a time from the bottom, and the
/// lowest block with a position wins: the position the sequential search finds, for any thread
/// count. On beast.obj (1,881 charts in 1024 x 1024) the search was 90 % of the bake.
bool findPosition(const Occupancy& occupied, const Mask& mask, int padding, int yLimit, int& px, int& py) {
    const int last = std::min(occupied.height() - mask.height, yLimit);  // the highest lower row
    struct Found {
        bool found = false;
        int x = 0, y = 0;
    };
    std::array<Found, kSearchBlocks> wave;
    // Two blocks per thread (blocks above the first hit are wasted work), one on one thread.
    const int threads = std::min(tbb::this_task_arena::max_concurrency(),
                                 int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)));
    const int perWave = threads > 1 ? std::min(2 * threads, kSearchBlocks) : 1;
    for (int base = 0; base <= last; base += kSearchRows * perWave) {
        const int blocks = std::min(perWave, (last - base) / kSearchRows + 1);
        auto search = [&](int b) {
            const int begin = base + b * kSearchRows, end = std::min(begin + kSearchRows, last + 1);
            wave[size_t(b)].found = findInRows(occupied, mask, padding, begin, end, wave[size_t(b)].x, wave[size_t(b)].y);
        };
        if (blocks == 1) search(0);
        else tbb::parallel_for(0, blocks, search);
        for (int b = 0; b < blocks; ++b)
            if (wave[size_t(b)].found) return px = wave[size_t(b)].x, py = wave[size_t(b)].y, true;
    }
    return false;
}

void reserve(Occupancy& occupied, const Mask& mask, int padding, int x, int y) {
    const RowRuns& d = mask.dilated;
    for (int row = 0; row < d.rows(); ++row) {
        const int atlasRow = y + row - padding;
        if (atlasRow < 0 || atlasRow >= occupied.height()) continue;
        for (uint32_t r = d.start[size_t(row)]; r < d.start[size_t(row) + 1]; ++r)
            occupied.set(atlasRow, std::max(0, x + d.runs[r].first), std::min(occupied.width(), x + d.runs[r].second));
    }
}

/// Every chart's masks at density s, in each of the kTurns orientations.
struct Masks {
    std::vector<std::array<Mask, kTurns>> of;
    std::vector<uint32_t> order;  ///< charts largest first
};

/// Whether every chart, at density s, fits a width x height atlas in one of its orientations:
/// checked before any mask is made, so that a density far too high never allocates masks
/// larger than the atlas.
bool chartsFit(std::span<const Chart> charts, double s, int width, int height) {
    for (const Chart& chart : charts) {
        const glm::dvec2 e = chart.size * s + glm::dvec2(1.0);
        if (!((e.x <= width && e.y <= height) || (e.y <= width && e.x <= height))) return false;
    }
    return true;
}

Masks makeMasks(std::span<const Chart> charts, double s, int padding) {
    Masks masks;
    masks.of.resize(charts.size());
    tbb::parallel_for(size_t(0), charts.size() * kTurns, [&](size_t i) {
        masks.of[i / kTurns][i % kTurns] = makeMask(charts[i / kTurns], s, int(i % kTurns), padding);
    });
    masks.order.resize(charts.size());
    std::iota(masks.order.begin(), masks.order.end(), 0u);
    auto area = [&](uint32_t c) { return int64_t(masks.of[c][0].width) * masks.of[c][0].height; };
    std::stable_sort(masks.order.begin(), masks.order.end(), [&](uint32_t a, uint32_t b) { return area(a) > area(b); });
    return masks;
}

/// Places every chart into a width x height atlas (height may be a generous cap: the used
/// height is returned in @p usedHeight, the used width in @p usedWidth); false when one does not fit.
bool placeAll(const Masks& masks, int padding, int width, int height, std::vector<ChartPlacement>& placement,
              int& usedWidth, int& usedHeight, ProgressReporter* progress) {
    Occupancy occupied(width, height, padding);
    placement.assign(masks.of.size(), ChartPlacement{});
    usedWidth = usedHeight = 0;
    for (uint32_t c : masks.order) {
        // The orientation whose top ends lowest, then the lowest, then the leftmost.
        int bestTurn = -1;
        std::array<int, 3> best{};
        for (int turn = 0; turn < kTurns; ++turn) {
            int x = 0, y = 0;
            const int maskHeight = masks.of[c][size_t(turn)].height;
            // Only positions whose top is not above the best one's can win.
            const int yLimit = bestTurn < 0 ? INT32_MAX : best[0] - maskHeight;
            if (!findPosition(occupied, masks.of[c][size_t(turn)], padding, yLimit, x, y)) continue;
            const std::array<int, 3> key{y + maskHeight, y, x};
            if (bestTurn < 0 || key < best) best = key, bestTurn = turn, placement[c] = ChartPlacement{x, y, turn};
        }
        if (progress) progress->update();
        if (bestTurn < 0) return false;
        const Mask& mask = masks.of[c][size_t(bestTurn)];
        reserve(occupied, mask, padding, placement[c].x, placement[c].y);
        usedWidth = std::max(usedWidth, placement[c].x + mask.width);
        usedHeight = std::max(usedHeight, placement[c].y + mask.height);
    }
    return true;
}

double totalArea(std::span<const Chart> charts) {
    double area = 0;
    for (const Chart& chart : charts) area += chart.area;
    return area;
}

/// The largest density (by bisection, to kDensityPrecision) at which every chart fits a width x
/// height atlas.
AtlasPacking packFixedSize(std::span<const Chart> charts, int padding, int width, int height, ProgressReporter* progress) {
    AtlasPacking best;
    const double area = totalArea(charts);
    if (!(area > 0)) {  // nothing to lay out, or only degenerate charts: any density fits
        std::vector<ChartPlacement> placement;
        int usedWidth = 0, usedHeight = 0;
        if (placeAll(makeMasks(charts, 1.0, padding), padding, width, height, placement, usedWidth, usedHeight, progress))
            best = AtlasPacking{width, height, 1.0, false, placement};
        return best;
    }
    // Covered texels hold at least the charts' projected area, which is at least cos(limit) of
    // their surface area (ChartParameterization.h): 1.5 is above 1 / sqrt(cos 55 deg).
    const double bound = std::sqrt(double(width) * height / area);
    double lo = 0, hi = 1.5 * bound;
    std::vector<ChartPlacement> placement;
    for (int iteration = 0; iteration < kMaxBisections && hi - lo > kDensityPrecision * hi; ++iteration) {
        // Start near where packings of lightmap charts usually end.
        const double s = iteration == 0 ? 0.8 * bound : 0.5 * (lo + hi);
        int usedWidth = 0, usedHeight = 0;
        if (chartsFit(charts, s, width, height) &&
            placeAll(makeMasks(charts, s, padding), padding, width, height, placement, usedWidth, usedHeight, progress)) {
            lo = s;
            best = AtlasPacking{width, height, s, false, placement};
        } else {
            hi = s;
        }
    }
    return best;
}

int ceilPowerOfTwo(int64_t x) { return int(std::bit_ceil(uint64_t(std::max<int64_t>(x, 1)))); }

/// The smallest atlas holding every chart at density s, over candidate widths.
AtlasPacking packFixedDensity(std::span<const Chart> charts, const AtlasPackOptions& options) {
    const int padding = options.padding;
    const double s = options.texelsPerUnit;
    if (!chartsFit(charts, s, options.maxSide, options.maxSide)) return AtlasPacking{};
    const Masks masks = makeMasks(charts, s, padding);
    int64_t reserved = 0;
    int narrowest = 1;  // every chart fits this wide in some orientation
    for (size_t c = 0; c < charts.size(); ++c) {
        for (const auto& [lo, hi] : masks.of[c][0].dilated.runs) reserved += hi - lo;  // a lower bound of the area
        narrowest = std::max(narrowest, std::min(masks.of[c][0].width, masks.of[c][1].width));
    }
    std::vector<int> widths;
    const double side = std::sqrt(double(reserved));
    if (options.powerOfTwo) {
        // Sides from half to twice the area's: narrower or wider ones only make longer strips.
        for (int64_t w = ceilPowerOfTwo(std::max<int64_t>(narrowest, int64_t(side / 2))); w <= options.maxSide && w <= 2 * int64_t(side) + 64; w *= 2)
            widths.push_back(int(w));
    } else {
        for (int k = 0; k <= 4; ++k) widths.push_back(std::max(narrowest, int(std::ceil(side * (1.0 + 0.08 * k)))));
    }
    AtlasPacking best;
    std::vector<ChartPlacement> placement;
    for (int width : widths) {
        if (width > options.maxSide) continue;
        int usedWidth = 0, usedHeight = 0;
        if (!placeAll(masks, padding, width, options.maxSide, placement, usedWidth, usedHeight, options.progress)) continue;
        int w = std::max(usedWidth, 1), h = std::max(usedHeight, 1);
        if (options.powerOfTwo) w = width, h = ceilPowerOfTwo(h);
        if (h > options.maxSide) continue;
        const int64_t area = int64_t(w) * h, bestArea = int64_t(best.width) * best.height;
        if (best.width == 0 || area < bestArea || (area == bestArea && std::max(w, h) < std::max(best.width, best.height)))
            best = AtlasPacking{w, h, s, false, placement};
    }
    return best;
}

}  // namespace

AtlasPacking packAtlas(std::span<const Chart> charts, const AtlasPackOptions& options) {
    if (options.texelsPerUnit > 0) {
        AtlasPacking packing = packFixedDensity(charts, options);
        if (packing.width > 0) return packing;
        int side = options.maxSide;
        if (options.powerOfTwo) side = int(std::bit_floor(uint64_t(side)));
        packing = packFixedSize(charts, options.padding, side, side, options.progress);
        packing.densityLowered = true;
        return packing;
    }
    return packFixedSize(charts, options.padding, options.width, options.height, options.progress);
}

uint64_t expectedPlacements(size_t charts, const AtlasPackOptions& options) {
    constexpr uint64_t kBisections = 10, kWidths = 5;  // what packFixedSize and packFixedDensity try
    return uint64_t(charts) * (options.texelsPerUnit > 0 ? kWidths : kBisections);
}

glm::dvec2 atlasTexel(const Chart& chart, const ChartPlacement& placement, double texelsPerUnit, size_t vertex) {
    return localTexel(chart, placement.turns, texelsPerUnit, chart.uv[vertex]) + glm::dvec2(placement.x, placement.y);
}

}  // namespace penumbra
