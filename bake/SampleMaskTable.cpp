#include "bake/SampleMaskTable.h"

#include <glm/geometric.hpp>
#include <glm/gtc/constants.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace penumbra {
namespace {

constexpr double kRoundoff = 0x1p-53;  // u: unit roundoff of double
/// Angular slack of a table cell: the cell's masks hold for every line whose angle is within this
/// of the cell's range, which covers atan2's error and the rounding of the bin index many times.
constexpr double kAngleSlack = 1e-9;
/// Samples farther than this (relative to the light's radius) from the fitted plane: the light is
/// volumetric (a sphere), and the table would decide almost nothing.
constexpr double kMaxFlatness = 1e-4;

double maxAbs(const glm::dvec3& p) { return std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}); }

/// Is angle @p phi within [lo - slack, hi + slack], modulo 2 pi?
bool angleWithin(double phi, double lo, double hi) {
    double d = std::remainder(phi - 0.5 * (lo + hi), glm::two_pi<double>());
    return std::abs(d) <= 0.5 * (hi - lo) + kAngleSlack;
}

}  // namespace

SampleMaskTable::SampleMaskTable(const LightSamples& samples, uint32_t light, int angles, int offsets)
    : angles_(std::max(1, angles)), offsets_(std::max(1, offsets)) {
    firstGroup_ = samples.lightFirstGroup[light];
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
    // Slack for the rounding of these very measurements (a few ulps of the coordinates).
    flatness_ = flatness + 1e-12 * (maxAbs_ + radius);
    radius_ = radius * (1.0 + 1e-6);
    usable_ = true;

    // Local sample -> (group of the light, bit).
    std::vector<uint32_t> groupOf(count), bitOf(count);
    for (uint32_t k = 0; k < groups_; ++k) {
        const LightSampleGroup& g = samples.groups[firstGroup_ + k];
        for (uint32_t j = 0; j < g.count; ++j) groupOf[g.first - first + j] = k, bitOf[g.first - first + j] = j;
    }
    const size_t rows = size_t(samples.sets) * angles_ * (offsets_ + 2);
    sure_.assign(rows * groups_, 0);
    maybe_.assign(rows * groups_, 0);
    const double step = glm::two_pi<double>() / angles_;
    for (int set = 0; set < samples.sets; ++set)
        for (int a = 0; a < angles_; ++a) {
            const double t0 = -glm::pi<double>() + a * step, t1 = t0 + step;
            const glm::dvec2 d0(std::cos(t0), std::sin(t0)), d1(std::cos(t1), std::sin(t1));
            for (uint32_t k = 0; k < count; ++k) {
                const glm::dvec2 q = coords[size_t(set) * count + k];
                // Extremes of dot(dir(theta), q) over the cell's angles: at an end of the range,
                // or |q| when q's own direction (or its opposite) lies inside it.
                const double p0 = glm::dot(d0, q), p1 = glm::dot(d1, q), len = glm::length(q);
                const double phi = std::atan2(q.y, q.x);
                double lowest = std::min(p0, p1), highest = std::max(p0, p1);
                if (angleWithin(phi, t0, t1)) highest = len;
                if (angleWithin(phi + glm::pi<double>(), t0, t1)) lowest = -len;
                // Widen by the angular slack and by the rounding of the dot products.
                lowest -= kAngleSlack * radius_;
                highest += kAngleSlack * radius_;
                // sure in bin b  <=>  upper(b) <= lowest; maybe in bin b  <=>  lower(b) <= highest.
                // Both are prefixes of the bins, found with the same bin bounds lookup() uses.
                const int sureLast = offsetBin(lowest) - 1;  // upper(b - 1) == lower(b) <= lowest < upper(b)
                const int maybeLast = offsetBin(highest);
                const uint64_t bit = 1ull << bitOf[k];
                for (int b = 0; b <= sureLast; ++b) sure_[row(uint32_t(set), a, b) + groupOf[k]] |= bit;
                for (int b = 0; b <= maybeLast; ++b) maybe_[row(uint32_t(set), a, b) + groupOf[k]] |= bit;
            }
        }
}

double SampleMaskTable::lower(int bin) const {
    return bin == 0 ? -std::numeric_limits<double>::infinity() : -radius_ + (bin - 1) * (2.0 * radius_ / offsets_);
}

double SampleMaskTable::upper(int bin) const {
    return bin == offsets_ + 1 ? std::numeric_limits<double>::infinity() : -radius_ + bin * (2.0 * radius_ / offsets_);
}

int SampleMaskTable::offsetBin(double x) const {
    // The bin b with lower(b) <= x < upper(b); bins 0 and offsets_+1 are the open ends. The
    // estimate is corrected against the very bounds the table was built with, so the answer does
    // not depend on how the division rounds.
    double estimate = std::floor((x + radius_) / (2.0 * radius_ / offsets_)) + 1.0;
    int b = int(std::clamp(estimate, 0.0, double(offsets_ + 1)));
    while (b > 0 && x < lower(b)) --b;
    while (b < offsets_ + 1 && x >= upper(b)) ++b;
    return b;
}

SampleMaskTable::Blocker SampleMaskTable::prepare(const BlockerTriangle& t) const {
    Blocker out;
    if (!usable_ || !t.valid) return out;
    for (int i = 0; i < 3; ++i) out.v[i] = t.v[i];
    out.maxAbs = std::max({maxAbs_, maxAbs(t.v[0]), maxAbs(t.v[1]), maxAbs(t.v[2])});
    const double m = out.maxAbs, u = kRoundoff;
    // Every sample lies in the box [lo_, hi_]; an affine function's extremes over the box are at
    // its corners. BlockingRule's per-sample values differ from the real affine ones by at most
    // ~18 u M (the side, T's plane at l) and ~384 u M^3 (det(a-l, b-l, c-l), see lookup()); the
    // corners are evaluated with similar error. Demanding 64 u M and 2048 u M^3 at every corner
    // leaves the sign of every sample's computed value certain, so side and sigma are the same for
    // all samples of the light, as makeHardShadowVolume() will compute them.
    const glm::dvec3 normal = glm::cross(t.v[0] - t.v[2], t.v[1] - t.v[2]);  // G(l) = -normal . (l - v2)
    double sideMin = INFINITY, sideMax = -INFINITY, gMin = INFINITY, gMax = -INFINITY;
    for (int c = 0; c < 8; ++c) {
        glm::dvec3 x((c & 1) ? hi_.x : lo_.x, (c & 2) ? hi_.y : lo_.y, (c & 4) ? hi_.z : lo_.z);
        double s = t.plane.eval(x), g = -glm::dot(normal, x - t.v[2]);
        sideMin = std::min(sideMin, s), sideMax = std::max(sideMax, s);
        gMin = std::min(gMin, g), gMax = std::max(gMax, g);
    }
    const double sideMargin = 64 * u * m, gMargin = 2048 * u * m * m * m;
    if (sideMin > sideMargin) out.side = -1.0;       // sl > 0 for every sample
    else if (sideMax < -sideMargin) out.side = 1.0;  // sl < 0 for every sample
    else return out;
    if (gMin > gMargin) out.sigma = 1.0;
    else if (gMax < -gMargin) out.sigma = -1.0;
    else return out;
    out.usable = true;
    return out;
}

SampleMaskTable::Lookup SampleMaskTable::lookup(const Blocker& b, uint32_t set, const glm::dvec3& r, double dist,
                                                double eps, Rows& rows) const {
    if (!b.usable) return Lookup::Exact;
    // BlockingRule's first clause, with the side every sample shares: the same double expression.
    if (!(b.side * dist > eps)) return Lookup::NoneBlocked;
    const double m = std::max(b.maxAbs, maxAbs(r)), u = kRoundoff;
    const double step = glm::two_pi<double>() / angles_;
    // Error budget, every coordinate bounded by M (= m):
    //  - BlockingRule computes edge value E(l) = sigma * fl(det(a-l, b-l, r-l)). Differences are
    //    within 2M, the cross product's components within 8M^2 with error 32uM^2, the two dot
    //    products and the sum add 192uM^3, and the cross product's error times |r-l|_1 <= 6M adds
    //    192uM^3: |E(l) - sigma*det| <= 384uM^3 =: beta (the code uses 2048uM^3 for beta).
    //  - In real arithmetic det(a-l, b-l, r-l) = -mr . (l - r) with mr = (a-r) x (b-r). Computed,
    //    m has error 32uM^2 per component: 256uM^3 on the value.
    //  - l - o = s u + t v + h n + e: |h| <= H (flatness_), |e| <= 8u|l-o|; the table holds the
    //    computed (s, t). With w = -sigma (m.u, m.v), k = -sigma m.(o-r) the rounding of w, k, the
    //    frame and the h term add at most |m| (H + 128uM).
    //  - Normalising by g = |w| (so the offset is tau = -k/g) and the angle binning (covered in
    //    the table by kAngleSlack) add a few ulps of R and tau.
    // So sigma*det > beta whenever dot(dir, q) > tau + delta with
    //    delta = ((2048 + 256) u M^3 + |m| (H + 128uM)) / g + 4u (R + |tau|),
    // and sigma*det < -beta whenever dot(dir, q) < tau - delta; then E(l) >= 0 (resp. < 0) for
    // certain. The code doubles delta and rounds the last term up to 1e-12, which costs nothing
    // measurable: delta stays many orders of magnitude below a cell.
    const double fixed = 2304 * u * m * m * m;
    for (int e = 0; e < 3; ++e) {
        const glm::dvec3 mr = glm::cross(b.v[e] - r, b.v[(e + 1) % 3] - r);
        const double wx = -b.sigma * glm::dot(mr, u_), wy = -b.sigma * glm::dot(mr, v_);
        const double k = -b.sigma * glm::dot(mr, origin_ - r);
        const double g = std::sqrt(wx * wx + wy * wy), tau = -k / g;
        const double delta = 2.0 * ((fixed + glm::length(mr) * (flatness_ + 128 * u * m)) / g) + 1e-12 * (radius_ + std::abs(tau));
        // A line this uncertain (a plane nearly parallel to the light, or g == 0) decides little.
        if (!(delta < radius_) || !std::isfinite(tau)) return Lookup::Exact;
        int a = int((std::atan2(wy, wx) + glm::pi<double>()) / step);
        a = std::clamp(a, 0, angles_ - 1);
        rows.sure[e] = &sure_[row(set, a, offsetBin(tau + delta))];
        rows.maybe[e] = &maybe_[row(set, a, offsetBin(tau - delta))];
    }
    return Lookup::Rows;
}

}  // namespace penumbra
