/// @file SampleMaskTableFootprint.cpp
/// @brief SampleMaskTable::footprint(): the box of the light's plane that can hold a split
/// blocker's blocked samples, seen from one receiver, bounded with lookup()'s error budget.
///
/// lookup() shows (SampleMaskTable.cpp) that for a sample whose frame coordinates, as the table
/// computed them, are q = (s, t), the rule's edge value E_e(l) >= 0 implies
///     w_e . q + k_e >= -Delta_e,   Delta_e = delta_e g_e,
/// with w_e = (wx, wy), k_e the edge's line coefficients at r in the orientation of the samples
/// that can be blocked, g_e = |w_e|_1 and delta_e the margin lineRows() derives. So every blocked
/// sample lies in P, the intersection of the three half-planes w_e . q + c_e >= 0 with
/// c_e = k_e + Delta_e (the coefficients as computed, now taken as exact reals).
///
/// When the three inward normals w_e positively span the plane (their three cross products
/// d_ij = w_i x w_j share one strict sign), P is bounded: a triangle, possibly empty, whose
/// vertices are the pairwise intersections V_ij of the lines w_i . q = -c_i, w_j . q = -c_j. The
/// box of the three computed vertices, each widened by a bound of its rounding, then holds P.
/// A pair of lines within 1e-4 (relative) of parallel is left to the other tests. Samples are
/// binned by a monotone function of their coordinate, so a sample inside the box lies in a bin
/// between the box ends' bins.
///
/// Rounding of one vertex, x = N / d with N = -c_i wy_j + c_j wy_i and d = d_ij: the computed N and
/// d are within 2u N_abs and 2u D of the exact ones (N_abs = |c_i wy_j| + |c_j wy_i|, D = |wx_i wy_j|
/// + |wy_i wx_j|), so the computed x is within 2u (N_abs + |x| D) / |d| + u |x| of the exact
/// quotient (|d| >= 1e-4 D keeps the relative error of d below 3e4 u). The code multiplies by a
/// computed 1/d (one more rounding, u |x|) and doubles each term; the AVX2 form computes the same
/// expressions for four receivers at a time, one per lane.
/// The sums c_e = k_e + Delta_e round by at most u (|k_e| + Delta_e), far inside Delta_e's own
/// factor-two slack (Delta_e >= 1e-12 |k_e|).

#include "bake/cast/SampleMaskTable.h"

#include <algorithm>
#include <cmath>

namespace penumbra {

void SampleMaskTable::buildFootprintBins(const std::vector<glm::dvec2>& coords, const std::vector<uint32_t>& groupOf,
                                         const std::vector<uint32_t>& bitOf, int sets) {
    for (int axis = 0; axis < 2; ++axis) {
        double lo = INFINITY, hi = -INFINITY;
        for (const glm::dvec2& q : coords) lo = std::min(lo, q[axis]), hi = std::max(hi, q[axis]);
        binLow_[axis] = lo;
        // A light of no extent along an axis (a line light) puts every sample in bin 0.
        binScale_[axis] = hi > lo ? kFootprintBins / (hi - lo) : 0.0;
    }
    const size_t count = coords.size() / size_t(sets);
    footprintRows_.assign(size_t(sets) * 4 * kFootprintBins * groups_, 0);
    for (int set = 0; set < sets; ++set)
        for (size_t k = 0; k < count; ++k) {
            const glm::dvec2 q = coords[size_t(set) * count + k];
            const uint64_t bit = 1ull << bitOf[k];
            for (int axis = 0; axis < 2; ++axis) {
                const int own = footprintBin(axis, q[axis]);
                for (int bin = 0; bin <= own; ++bin) footprintRows_[footprintIndex(uint32_t(set), axis, 0, bin) + groupOf[k]] |= bit;
                for (int bin = own; bin < kFootprintBins; ++bin) footprintRows_[footprintIndex(uint32_t(set), axis, 1, bin) + groupOf[k]] |= bit;
            }
        }
}

int SampleMaskTable::footprintBin(int axis, double value) const {
    // Subtraction and multiplication by a positive constant round monotonically, and so do floor
    // and the clamp: a larger value never gets a smaller bin. Callers pass finite values only.
    return int(std::clamp(std::floor((value - binLow_[axis]) * binScale_[axis]), 0.0, double(kFootprintBins - 1)));
}

bool SampleMaskTable::footprintBins(const Blocker& b, const glm::dvec3& r, double s, double m, int bins[4]) const {
    const double u = kRoundoff, fixed = 4096 * u * m * m * m;
    double wx[3], wy[3], c[3];
    for (int e = 0; e < 3; ++e) {
        wx[e] = s * b.line.at(0, e, r), wy[e] = s * b.line.at(1, e, r);
        const double k = s * b.line.at(2, e, r), mn = b.line.at(3, e, r);
        const double g = std::abs(wx[e]) + std::abs(wy[e]), norm1 = g + std::abs(mn);
        // lineRows()'s delta times g, doubled.
        c[e] = k + 2.0 * (lineMargin(norm1, fixed, m) + 1e-12 * (radius_ * g + std::abs(k)));
    }
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    int sign = 0;
    for (int i = 0; i < 3; ++i) {
        const int j = (i + 1) % 3;
        const double p = wx[i] * wy[j], q = wy[i] * wx[j], d = p - q, dAbs = std::abs(p) + std::abs(q);
        if (!(std::abs(d) >= kMinimumFootprintSine * dAbs) || !(dAbs > 0)) return false;  // NaN too
        const int dSign = d > 0 ? 1 : -1;
        if (sign != 0 && dSign != sign) return false;  // P unbounded
        sign = dSign;
        const double inverse = 1.0 / d;
        const double a1 = c[i] * wy[j], a2 = c[j] * wy[i], b1 = wx[i] * c[j], b2 = wx[j] * c[i];
        const double vertex[2] = {(a2 - a1) * inverse, (b2 - b1) * inverse};
        const double numeratorAbs[2] = {std::abs(a1) + std::abs(a2), std::abs(b1) + std::abs(b2)};
        for (int axis = 0; axis < 2; ++axis) {
            const double x = vertex[axis];
            const double margin = 4 * u * ((numeratorAbs[axis] + std::abs(x) * dAbs) * std::abs(inverse) + std::abs(x));
            lo[axis] = std::min(lo[axis], x - margin), hi[axis] = std::max(hi[axis], x + margin);
        }
    }
    for (int axis = 0; axis < 2; ++axis) {
        if (!std::isfinite(lo[axis]) || !std::isfinite(hi[axis])) return false;
        bins[2 * axis] = footprintBin(axis, lo[axis]), bins[2 * axis + 1] = footprintBin(axis, hi[axis]);
    }
    return true;
}

void SampleMaskTable::footprints(const Blocker& b, const glm::dvec3* r, const uint32_t* set, const double* dist, const double* eps,
                                 uint32_t live, FootprintResult* result, Footprint* out) const {
    // As in lookup(): only samples on the far side of T from r can be blocked, all with the
    // orientation s; a receiver within eps of T's plane is blocked by none.
    double s[4], m[4];
    glm::dvec3 at[4];
    uint32_t pending = 0;
    for (uint32_t rest = live; rest; rest &= rest - 1) {
        const int i = __builtin_ctz(rest);
        result[i] = FootprintResult::Unknown;
        if (!b.usable || !b.split) continue;
        if (!(-dist[i] > eps[i]) && !(dist[i] > eps[i])) {
            result[i] = FootprintResult::NoneBlocked;
            continue;
        }
        s[i] = -dist[i] > eps[i] ? 1.0 : -1.0, m[i] = std::max(b.maxAbs, maxAbs(r[i])), at[i] = r[i];
        pending |= 1u << i;
    }
    if (!pending) return;
    int bins[4][4];
    uint32_t boxes = 0;
    if (avx2_) {
        const int first = __builtin_ctz(pending);
        for (int i = 0; i < 4; ++i)
            if (!(pending >> i & 1)) s[i] = s[first], m[i] = m[first], at[i] = at[first];  // lanes computed and ignored
        boxes = footprintBins4Avx2(b, at, s, m, bins) & pending;
    } else {
        for (uint32_t rest = pending; rest; rest &= rest - 1) {
            const int i = __builtin_ctz(rest);
            int one[4];
            if (!footprintBins(b, at[i], s[i], m[i], one)) continue;
            for (int end = 0; end < 4; ++end) bins[end][i] = one[end];
            boxes |= 1u << i;
        }
    }
    for (uint32_t rest = boxes; rest; rest &= rest - 1) {
        const int i = __builtin_ctz(rest);
        result[i] = FootprintResult::Box;
        out[i].sLow = footprintRow(set[i], 0, 0, bins[0][i]), out[i].sHigh = footprintRow(set[i], 0, 1, bins[1][i]);
        out[i].tLow = footprintRow(set[i], 1, 0, bins[2][i]), out[i].tHigh = footprintRow(set[i], 1, 1, bins[3][i]);
    }
}

}  // namespace penumbra
