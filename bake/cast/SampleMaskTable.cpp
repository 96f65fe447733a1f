#include "bake/cast/SampleMaskTable.h"

#include <glm/geometric.hpp>
#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace penumbra {
namespace {

/// Slack of a table cell in diamond angle: the cell's masks hold for every line whose diamond
/// angle is within this of the cell's range, which covers the rounding of the diamond angle and
/// of the bin index many times.
constexpr double kAngleSlack = 1e-9;
/// Samples farther than this (relative to the light's radius) from the fitted plane: the light is
/// volumetric (a sphere), and the table would decide almost nothing.
constexpr double kMaxFlatness = 1e-4;
/// A light whose table would be larger than this (many samples times many sets) gets none: the
/// table must stay small next to the receivers, and cache-resident enough to pay off.
constexpr size_t kMaxTableBytes = size_t(64) << 20;

int angleBins(int angles) { return std::max(4, (angles + 3) / 4 * 4); }  // cells within a quadrant

/// The direction of 1-norm 1 whose diamond angle is @p p, for p in [0, 4]. The diamond angle
/// increases with the polar angle over [0, 4) (one quadrant per unit) and, unlike the polar
/// angle, moves the unit-1-norm direction linearly within a quadrant; so dot(direction, q) is
/// linear in it and its extremes over a cell are at the cell's ends.
glm::dvec2 diamondDirection(double p) {
    const int quadrant = std::min(3, int(p));
    const double f = p - quadrant;
    switch (quadrant) {
        case 0: return {1 - f, f};
        case 1: return {-f, 1 - f};
        case 2: return {f - 1, -f};
        default: return {f, f - 1};
    }
}


}  // namespace

SampleMaskTable::SampleMaskTable(const LightSamples& samples, uint32_t light, int angles, int offsets, SimdLevel simd)
    : angles_(angleBins(angles)), offsets_(std::max(1, offsets)) {
    avx2_ = hardShadowKernels(simd).level == SimdLevel::Avx2;  // Auto resolved, and refused if unsupported, in one place
    firstGroup_ = samples.lightFirstGroup[light];
    w_ = samples.w(light);
    groups_ = samples.lightFirstGroup[light + 1] - firstGroup_;
    if (groups_ == 0) return;
    const uint32_t first = samples.groups[firstGroup_].first;
    const uint32_t count = samples.groups[firstGroup_ + groups_ - 1].first +
                           samples.groups[firstGroup_ + groups_ - 1].count - first;
    std::vector<glm::dvec3> points;  // [set][sample of the light]
    points.reserve(size_t(samples.sets) * count);
    for (int set = 0; set < samples.sets; ++set)
        for (uint32_t k = 0; k < count; ++k) points.push_back(glm::dvec3(samples.position(set, int(first + k))));

    // The plane through three far-apart samples; how flat the light is gets measured below, so the
    // choice only needs to be good, not optimal. Sphere lights are rejected by the flatness test.
    glm::dvec3 centroid(0.0);
    lo_ = hi_ = points[0];
    for (const glm::dvec3& p : points) centroid += p, lo_ = glm::min(lo_, p), hi_ = glm::max(hi_, p);
    centroid /= double(points.size());
    maxAbs_ = std::max(maxAbs(lo_), maxAbs(hi_));
    auto farthestFrom = [&](const glm::dvec3& q) {
        return *std::max_element(points.begin(), points.end(), [&](const glm::dvec3& a, const glm::dvec3& b) {
            return glm::length(a - q) < glm::length(b - q);
        });
    };
    const glm::dvec3 p0 = farthestFrom(centroid), p1 = farthestFrom(p0);
    const glm::dvec3 p2 = *std::max_element(points.begin(), points.end(), [&](const glm::dvec3& a, const glm::dvec3& b) {
        return glm::length(glm::cross(p1 - p0, a - p0)) < glm::length(glm::cross(p1 - p0, b - p0));
    });
    glm::dvec3 normal = glm::cross(p1 - p0, p2 - p0);
    if (!(glm::length(normal) > 0.0)) return;  // one sample, or all on a line
    origin_ = centroid;
    n_ = glm::normalize(normal);
    u_ = glm::normalize((p1 - p0) - glm::dot(p1 - p0, n_) * n_);
    v_ = glm::cross(n_, u_);

    std::vector<glm::dvec2> coords(points.size());
    double radius = 0, flatness = 0;
    for (size_t i = 0; i < points.size(); ++i) {
        glm::dvec3 d = points[i] - origin_;
        coords[i] = {glm::dot(u_, d), glm::dot(v_, d)};
        radius = std::max(radius, glm::length(coords[i]));
        flatness = std::max(flatness, std::abs(glm::dot(n_, d)));
    }
    if (!(radius > 0.0) || flatness > kMaxFlatness * radius) return;
    const size_t words = cellBytes(samples, light, angles_, offsets_) / sizeof(uint64_t);
    if (words == 0) return;
    // Slack for the rounding of these very measurements (a few ulps of the coordinates).
    flatness_ = flatness + 1e-12 * (maxAbs_ + radius);
    radius_ = radius * (1.0 + 1e-6);
    width_ = 2.0 * radius_ / offsets_;
    invWidth_ = offsets_ / (2.0 * radius_);
    usable_ = true;

    // Local sample -> (group of the light, bit).
    std::vector<uint32_t> groupOf(count), bitOf(count);
    for (uint32_t k = 0; k < groups_; ++k) {
        const LightSampleGroup& g = samples.groups[firstGroup_ + k];
        for (uint32_t j = 0; j < g.count; ++j) groupOf[g.first - first + j] = k, bitOf[g.first - first + j] = j;
    }
    buildFootprintBins(coords, groupOf, bitOf, samples.sets);
    cells_.assign(words, 0);
    ones_.assign(2 * size_t(groups_) + 1, ~0ull);
    for (int set = 0; set < samples.sets; ++set)
        for (int a = 0; a < angles_; ++a) {
            const glm::dvec2 d0 = diamondDirection(4.0 * a / angles_), d1 = diamondDirection(4.0 * (a + 1) / angles_);
            for (uint32_t k = 0; k < count; ++k) {
                const glm::dvec2 q = coords[size_t(set) * count + k];
                // Extremes of dot(direction, q) over the cell: at its ends (linear in the diamond
                // angle). Widened for the slack (the derivative is at most |q|_1 <= 2R) and for the
                // rounding of the dot products (far below that).
                const double p0 = glm::dot(d0, q), p1 = glm::dot(d1, q);
                const double lowest = std::min(p0, p1) - 4 * kAngleSlack * radius_;
                const double highest = std::max(p0, p1) + 4 * kAngleSlack * radius_;
                // sure in bin b  <=>  upper(b) <= lowest; maybe in bin b  <=>  lower(b) <= highest.
                // Both are prefixes of the bins; the last bin is found from the estimate and then
                // checked against the bounds themselves, so the cells mean exactly that.
                int sureLast = offsetBin(lowest) - 1, maybeLast = offsetBin(highest);
                while (sureLast >= 0 && upper(sureLast) > lowest) --sureLast;
                while (sureLast < offsets_ && upper(sureLast + 1) <= lowest) ++sureLast;
                while (maybeLast > 0 && lower(maybeLast) > highest) --maybeLast;
                while (maybeLast < offsets_ + 1 && lower(maybeLast + 1) <= highest) ++maybeLast;
                const uint64_t bit = 1ull << bitOf[k];
                for (int b = 0; b <= sureLast; ++b) cells_[cell(uint32_t(set), a, b) + 2 * groupOf[k]] |= bit;
                for (int b = 0; b <= maybeLast; ++b) cells_[cell(uint32_t(set), a, b) + 2 * groupOf[k] + 1] |= bit;
            }
        }
}

double SampleMaskTable::lower(int bin) const {
    return bin == 0 ? -std::numeric_limits<double>::infinity() : -radius_ + (bin - 1) * width_;
}

double SampleMaskTable::upper(int bin) const {
    return bin == offsets_ + 1 ? std::numeric_limits<double>::infinity() : -radius_ + bin * width_;
}

int SampleMaskTable::offsetBin(double x) const {
    // Bins 0 and offsets_+1 are the open ends. The result b satisfies lower(b) - e <= x <
    // upper(b) + e with e <= 8u (|x| + 3R) from the rounding of this product and of the bounds;
    // lookup()'s margin covers it. (Clamping first makes the truncation a floor and keeps NaN-free
    // finite input in range; this runs six times per receiver, so no division and no libm floor.)
    return int(std::clamp((x + radius_) * invWidth_ + 1.0, 0.0, double(offsets_ + 1)));
}

size_t SampleMaskTable::cellBytes(const LightSamples& samples, uint32_t light, int angles, int offsets) {
    const size_t groups = samples.lightFirstGroup[light + 1] - samples.lightFirstGroup[light];
    const size_t bytes = size_t(samples.sets) * angleBins(angles) * (std::max(1, offsets) + 2) * groups * 2 * sizeof(uint64_t);
    return bytes > kMaxTableBytes ? 0 : bytes;
}

size_t SampleMaskTable::plannedBytes(const LightSamples& samples, uint32_t light, int angles, int offsets) {
    const size_t cells = cellBytes(samples, light, angles, offsets);
    const size_t groups = samples.lightFirstGroup[light + 1] - samples.lightFirstGroup[light];
    return cells == 0 ? 0 : cells + size_t(samples.sets) * 4 * kFootprintBins * groups * sizeof(uint64_t);
}

SampleMaskTable::Blocker SampleMaskTable::prepare(const BlockerTriangle& t) const {
    Blocker out;
    if (!usable_ || !t.valid) return out;
    out.maxAbs = std::max({maxAbs_, maxAbs(t.v[0]), maxAbs(t.v[1]), maxAbs(t.v[2])});
    const double m = out.maxAbs, u = kRoundoff;
    // Every sample lies in the box [lo_, hi_]; T's side value n . (l - w v0) is affine in l, so its
    // extremes over the box are at the corners. The rule's per-sample value differs from the real
    // one by at most ~8 u M, and the corners are evaluated with similar error: demanding 64 u M at
    // every corner leaves the sign of every sample's computed value certain. That sign is the
    // orientation s of every edge plane too (BlockingRule.h), so all samples share side and s.
    double sideMin = INFINITY, sideMax = -INFINITY;
    for (int c = 0; c < 8; ++c) {
        glm::dvec3 x((c & 1) ? hi_.x : lo_.x, (c & 2) ? hi_.y : lo_.y, (c & 4) ? hi_.z : lo_.z);
        const double e = t.side(x, w_);
        sideMin = std::min(sideMin, e), sideMax = std::max(sideMax, e);
    }
    const double sideMargin = 64 * u * m;
    if (sideMin > sideMargin) out.side = -1.0;       // sl > 0 for every sample
    else if (sideMax < -sideMargin) out.side = 1.0;  // sl < 0 for every sample
    else out.split = true;                           // T's plane cuts the light: see lookup()
    out.sigma = out.split ? 1.0 : -out.side;
    if (out.split) {
        const glm::dvec3& n = t.plane.n;
        out.plane = {glm::dot(n, u_), glm::dot(n, v_), glm::dot(n, origin_ - w_ * t.v[0])};
        out.planeNormal = glm::dot(n, n_);
    }
    // E(l) = s (l - w a) . m with m = (b - a) x (r - a) = a x b - r x (b - a), so for a fixed
    // vector q, m . q = (a x b) . q - r . ((b - a) x q): affine in r. The line's coefficients are
    // m . u, m . v and m . (o - w a) = (a x b) . o - r . ((b - a) x (o - w a)), and m . n.
    for (int e = 0; e < 3; ++e) {
        const glm::dvec3 &a = t.v[e], &b = t.v[(e + 1) % 3];
        const glm::dvec3 ab = glm::cross(a, b), d = b - a;
        // Stored for orientation +1; lookup() applies the orientation (sigma, or per receiver
        // for a split blocker).
        out.line.set(0, e, glm::dot(ab, u_), glm::cross(d, u_));
        out.line.set(1, e, glm::dot(ab, v_), glm::cross(d, v_));
        out.line.set(2, e, glm::dot(ab, origin_), glm::cross(d, origin_ - w_ * a));
        out.line.set(3, e, glm::dot(ab, n_), glm::cross(d, n_));
    }
    out.line.repeatLastEdge();
    out.usable = true;
    return out;
}

SampleMaskTable::Lookup SampleMaskTable::lookup(const Blocker& b, uint32_t set, const glm::dvec3& r, double dist,
                                                double eps, Rows& rows) const {
    if (!b.usable) return Lookup::Exact;
    // BlockingRule's first clause, with the side every sample shares: the same double expression.
    if (!b.split && !(b.side * dist > eps)) return Lookup::NoneBlocked;
    const double m = std::max(b.maxAbs, maxAbs(r)), u = kRoundoff;
    // Error budget, every coordinate bounded by M (= m):
    //  - BlockingRule computes edge value E(l) = sigma * fl((l - w a) x (b - a) . (r - a)).
    //    Differences are within 2M with error 2uM, the cross product's components within 8M^2
    //    with error 40uM^2, the dot product's rounding adds 240uM^3, the cross product's error
    //    times |r-a|_1 <= 6M adds 240uM^3 and the error of r - a adds 48uM^3:
    //    |E(l) - sigma*det| <= 530uM^3 =: beta (the code uses 2048uM^3 for beta).
    //  - In real arithmetic det(l - w a, b - a, r - a) = m . (l - w a) with m = (b-a) x (r-a),
    //    and l - o = s u + t v + h n + e with |h| <= H (flatness_), |e| <= 8u|l-o|; the table
    //    holds the computed (s, t). So sigma*det = wx s + wy t + k + sigma (m.n) h + sigma m.e
    //    with w = sigma (m.u, m.v), k = sigma m.(o - w a): the h and e terms are at most
    //    |m| (H + 64uM), and |m| <= |wx| + |wy| + |m.n| (u, v, n orthonormal).
    //  - wx, wy, m.n, k come from prepare()'s affine forms: coefficients within 6M^2 and 6M
    //    (constant and linear part; 6M^3 and 8M^2 for k), rounding at most 160uM^2 on wx, wy, m.n
    //    and 240uM^3 on k; times |s| + |t| <= 2R <= 8M that is below 1600uM^3 =: 2048uM^3.
    //    (M bounds every coordinate of T, r and the samples; a sun's directions are about 1.)
    //    (Their own rounding on the |m| bound is O(u^2) and absorbed in 64uM -> 128uM.)
    //  - Normalising by g = |w|_1 (so the offset is tau = -k/g; any norm gives the same
    //    half-plane), the angle binning (covered in the table by kAngleSlack) and the offset
    //    binning (offsetBin()) add a few ulps of R and tau (at most 8u (|tau| + 4R)).
    //  - |m| is bounded by its 1-norm, which needs no square root.
    // So sigma*det > beta whenever dot(dir, q) > tau + delta with
    //    delta = ((2048 + 2048) u M^3 + |m| (H + 128uM)) / g + 40u (R + |tau|),
    // and sigma*det < -beta whenever dot(dir, q) < tau - delta; then E(l) >= 0 (resp. < 0) for
    // certain. The code doubles delta and rounds the last term up to 1e-12 (u = 1.1e-16), which
    // costs nothing measurable: delta stays many orders of magnitude below a cell.
    // Split blockers: only samples with s = sign(n . (l - w v0)) = -sign(dist) can pass the band
    // test, all with edge orientation s. T's plane is a fourth half-plane of the light's plane,
    // s (n.u s + n.v t + n.(o - w v0)) >= 0, whose value the rule computes with error under
    // 8uM; its coefficients' rounding over |s| + |t| <= 8M adds under 32uM (64uM used).
    double s = b.sigma;
    if (b.split) {
        if (!(-dist > eps) && !(dist > eps)) return Lookup::NoneBlocked;
        s = -dist > eps ? 1.0 : -1.0;
        if (!sideRows(b, set, s, m, rows.sure[3], rows.maybe[3])) return Lookup::Exact;
    } else {
        rows.sure[3] = ones_.data(), rows.maybe[3] = ones_.data() + 1;
    }
    const double fixed = 4096 * u * m * m * m;
    if (avx2_) return edgeRowsAvx2(b, set, r, s, fixed, m, rows) ? Lookup::Rows : Lookup::Exact;
    for (int e = 0; e < 3; ++e) {
        const double wx = s * b.line.at(0, e, r), wy = s * b.line.at(1, e, r), k = s * b.line.at(2, e, r);
        if (!lineRows(wx, wy, k, b.line.at(3, e, r), fixed, m, set, rows.sure[e], rows.maybe[e])) return Lookup::Exact;
    }
    return Lookup::Rows;
}

bool SampleMaskTable::sideRows(const Blocker& b, uint32_t set, double s, double m, const uint64_t*& sure,
                               const uint64_t*& maybe) const {
    // The plane line's margin uses the blocker's own scale, not the receiver's, so that the rows
    // are the same for every receiver (any M that bounds the samples and T is valid here).
    auto compute = [&] {
        return lineRows(s * b.plane.x, s * b.plane.y, s * b.plane.z, b.planeNormal, 64 * kRoundoff * b.maxAbs, b.maxAbs,
                        set, sure, maybe);
    };
    (void)m;
    if (!b.sideCache) return compute();
    const size_t i = size_t(set) * 2 + (s > 0.0);
    uint8_t& state = b.sideCache->state[i];
    if (state == 0) {
        state = compute() ? 1 : 2;
        if (state == 1) b.sideCache->rows[2 * i] = sure, b.sideCache->rows[2 * i + 1] = maybe;
    }
    sure = b.sideCache->rows[2 * i], maybe = b.sideCache->rows[2 * i + 1];
    return state == 1;
}

bool SampleMaskTable::lineRows(double wx, double wy, double k, double mn, double fixed, double m, uint32_t set,
                               const uint64_t*& sure, const uint64_t*& maybe) const {
    // Normalised by g = |w|_1, so the direction has 1-norm 1 and its diamond angle is one
    // component over g: one division per line, no square root, no atan2.
    const double ax = std::abs(wx), ay = std::abs(wy), invG = 1.0 / (ax + ay), tau = -k * invG;
    const double norm1 = ax + ay + std::abs(mn);
    const double delta = lineMargin(norm1, fixed, m) * invG + 1e-12 * (radius_ + std::abs(tau));
    // A line this uncertain (a plane nearly parallel to the light, or g == 0) decides little.
    if (!(delta < radius_) || !std::isfinite(tau)) return false;
    const double diamond = wy >= 0 ? (wx >= 0 ? wy * invG : 1 + ax * invG) : (wx < 0 ? 2 + ay * invG : 3 + ax * invG);
    const int a = std::clamp(int(diamond * (0.25 * angles_)), 0, angles_ - 1);
    sure = &cells_[cell(set, a, offsetBin(tau + delta))];
    maybe = &cells_[cell(set, a, offsetBin(tau - delta)) + 1];
    return true;
}

}  // namespace penumbra
