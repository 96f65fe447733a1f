/// @file SampleMaskTableAvx2.cpp
/// @brief SampleMaskTable::edgeRowsAvx2: a receiver's three edge lines looked up in one pass.
///
/// Lane e runs, operation for operation, what lineRows() runs for edge e (lane 3 repeats edge 2):
/// the affine forms in glm::dot's order, the one division, the margin, the diamond angle and the
/// two offset bins. The project builds with -ffp-contract=off and this file's target has no FMA,
/// so every lane rounds like the scalar code and finds the same rows; a test compares the two on
/// every lookup it makes (tests/bake/test_sample_mask_table.cpp). It exists because the three
/// calls, each with its own division and branches, were 15 % of GRIDS under a large light
/// (docs/performance.md).

#include "bake/cast/SampleMaskTable.h"

#include <immintrin.h>

namespace penumbra {
namespace {

/// c0 - ((cx rx + cy ry) + cz rz) per lane: Blocker::Lines::at().
PENUMBRA_AVX2 inline __m256d affineAt(const SampleMaskTable::Blocker::Lines& l, int j, __m256d rx, __m256d ry, __m256d rz) {
    const __m256d xy = _mm256_add_pd(_mm256_mul_pd(_mm256_load_pd(l.cx[j]), rx), _mm256_mul_pd(_mm256_load_pd(l.cy[j]), ry));
    return _mm256_sub_pd(_mm256_load_pd(l.c0[j]), _mm256_add_pd(xy, _mm256_mul_pd(_mm256_load_pd(l.cz[j]), rz)));
}

/// int(clamp(v, 0, hi)) per lane, for finite v (std::clamp's result, then truncation).
PENUMBRA_AVX2 inline __m128i clampedTruncation(__m256d v, double hi) {
    return _mm256_cvttpd_epi32(_mm256_min_pd(_mm256_max_pd(v, _mm256_setzero_pd()), _mm256_set1_pd(hi)));
}

}  // namespace

PENUMBRA_AVX2 bool SampleMaskTable::edgeRowsAvx2(const Blocker& b, uint32_t set, const glm::dvec3& r, double s, double fixed,
                                                 double m, Rows& rows) const {
    const __m256d rx = _mm256_set1_pd(r.x), ry = _mm256_set1_pd(r.y), rz = _mm256_set1_pd(r.z), sv = _mm256_set1_pd(s);
    const __m256d signBit = _mm256_set1_pd(-0.0), zero = _mm256_setzero_pd();
    const __m256d wx = _mm256_mul_pd(sv, affineAt(b.line, 0, rx, ry, rz));
    const __m256d wy = _mm256_mul_pd(sv, affineAt(b.line, 1, rx, ry, rz));
    const __m256d k = _mm256_mul_pd(sv, affineAt(b.line, 2, rx, ry, rz));
    const __m256d mn = affineAt(b.line, 3, rx, ry, rz);
    // lineRows(): invG = 1 / (|wx| + |wy|), tau = -k invG, norm1 = |wx| + |wy| + |mn|.
    const __m256d ax = _mm256_andnot_pd(signBit, wx), ay = _mm256_andnot_pd(signBit, wy);
    const __m256d g = _mm256_add_pd(ax, ay);
    const __m256d invG = _mm256_div_pd(_mm256_set1_pd(1.0), g);
    const __m256d tau = _mm256_mul_pd(_mm256_xor_pd(k, signBit), invG);
    const __m256d norm1 = _mm256_add_pd(g, _mm256_andnot_pd(signBit, mn));
    // delta = 2 (fixed + norm1 (H + 128 u m)) invG + 1e-12 (R + |tau|)
    const __m256d scaled = _mm256_add_pd(_mm256_set1_pd(fixed), _mm256_mul_pd(norm1, _mm256_set1_pd(flatness_ + 128 * kRoundoff * m)));
    const __m256d delta = _mm256_add_pd(_mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(2.0), scaled), invG),
                                        _mm256_mul_pd(_mm256_set1_pd(1e-12), _mm256_add_pd(_mm256_set1_pd(radius_), _mm256_andnot_pd(signBit, tau))));
    // Every lane must pass delta < R and finite tau (tau - tau is 0 only for finite tau).
    const __m256d ok = _mm256_and_pd(_mm256_cmp_pd(delta, _mm256_set1_pd(radius_), _CMP_LT_OQ),
                                     _mm256_cmp_pd(_mm256_sub_pd(tau, tau), zero, _CMP_EQ_OQ));
    if (_mm256_movemask_pd(ok) != 0xF) return false;
    // The diamond angle: wy >= 0 ? (wx >= 0 ? wy invG : 1 + ax invG) : (wx < 0 ? 2 + ay invG : 3 + ax invG).
    const __m256d axG = _mm256_mul_pd(ax, invG);
    const __m256d upper = _mm256_blendv_pd(_mm256_add_pd(_mm256_set1_pd(1.0), axG), _mm256_mul_pd(wy, invG),
                                           _mm256_cmp_pd(wx, zero, _CMP_GE_OQ));
    const __m256d lower = _mm256_blendv_pd(_mm256_add_pd(_mm256_set1_pd(3.0), axG),
                                           _mm256_add_pd(_mm256_set1_pd(2.0), _mm256_mul_pd(ay, invG)), _mm256_cmp_pd(wx, zero, _CMP_LT_OQ));
    const __m256d diamond = _mm256_blendv_pd(lower, upper, _mm256_cmp_pd(wy, zero, _CMP_GE_OQ));
    const __m128i angle = _mm_min_epi32(_mm_max_epi32(_mm256_cvttpd_epi32(_mm256_mul_pd(diamond, _mm256_set1_pd(0.25 * angles_))),
                                                      _mm_setzero_si128()),
                                        _mm_set1_epi32(angles_ - 1));
    // offsetBin(tau + delta) for sure, offsetBin(tau - delta) for maybe.
    const __m256d radius = _mm256_set1_pd(radius_), invWidth = _mm256_set1_pd(invWidth_), one = _mm256_set1_pd(1.0);
    auto bin = [&](__m256d x) PENUMBRA_AVX2 {
        return clampedTruncation(_mm256_add_pd(_mm256_mul_pd(_mm256_add_pd(x, radius), invWidth), one), double(offsets_ + 1));
    };
    alignas(16) int32_t a[4], sureBin[4], maybeBin[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(a), angle);
    _mm_store_si128(reinterpret_cast<__m128i*>(sureBin), bin(_mm256_add_pd(tau, delta)));
    _mm_store_si128(reinterpret_cast<__m128i*>(maybeBin), bin(_mm256_sub_pd(tau, delta)));
    for (int e = 0; e < 3; ++e) {
        rows.sure[e] = &cells_[cell(set, a[e], sureBin[e])];
        rows.maybe[e] = &cells_[cell(set, a[e], maybeBin[e]) + 1];
    }
    return true;
}

PENUMBRA_AVX2 uint32_t SampleMaskTable::footprintBins4Avx2(const Blocker& b, const glm::dvec3* r, const double* s, const double* m,
                                                          int bins[4][4]) const {
    // footprintBins() for four receivers, one per lane: the same expressions, and no horizontal
    // step (the three vertices are three vectors), so the four chains overlap.
    const __m256d rx = _mm256_setr_pd(r[0].x, r[1].x, r[2].x, r[3].x), ry = _mm256_setr_pd(r[0].y, r[1].y, r[2].y, r[3].y);
    const __m256d rz = _mm256_setr_pd(r[0].z, r[1].z, r[2].z, r[3].z), sv = _mm256_loadu_pd(s), mv = _mm256_loadu_pd(m);
    const __m256d signBit = _mm256_set1_pd(-0.0), u = _mm256_set1_pd(kRoundoff), zero = _mm256_setzero_pd();
    const __m256d fixed = _mm256_mul_pd(_mm256_set1_pd(4096 * kRoundoff), _mm256_mul_pd(_mm256_mul_pd(mv, mv), mv));
    const __m256d flat = _mm256_add_pd(_mm256_set1_pd(flatness_), _mm256_mul_pd(_mm256_set1_pd(128 * kRoundoff), mv));
    auto at = [&](int j, int e) PENUMBRA_AVX2 {
        const Blocker::Lines& l = b.line;
        const __m256d xy = _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(l.cx[j][e]), rx), _mm256_mul_pd(_mm256_set1_pd(l.cy[j][e]), ry));
        return _mm256_sub_pd(_mm256_set1_pd(l.c0[j][e]), _mm256_add_pd(xy, _mm256_mul_pd(_mm256_set1_pd(l.cz[j][e]), rz)));
    };
    __m256d wx[3], wy[3], c[3];
    for (int e = 0; e < 3; ++e) {
        wx[e] = _mm256_mul_pd(sv, at(0, e)), wy[e] = _mm256_mul_pd(sv, at(1, e));
        const __m256d k = _mm256_mul_pd(sv, at(2, e)), mn = at(3, e);
        const __m256d g = _mm256_add_pd(_mm256_andnot_pd(signBit, wx[e]), _mm256_andnot_pd(signBit, wy[e]));
        const __m256d norm1 = _mm256_add_pd(g, _mm256_andnot_pd(signBit, mn));
        const __m256d scaled = _mm256_add_pd(fixed, _mm256_mul_pd(norm1, flat));
        const __m256d slack = _mm256_mul_pd(_mm256_set1_pd(1e-12), _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(radius_), g),
                                                                                 _mm256_andnot_pd(signBit, k)));
        c[e] = _mm256_add_pd(k, _mm256_mul_pd(_mm256_set1_pd(2.0), _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(2.0), scaled), slack)));
    }
    __m256d ok = _mm256_cmp_pd(zero, zero, _CMP_EQ_OQ), sLow = _mm256_set1_pd(INFINITY), tLow = sLow;
    __m256d sHigh = _mm256_set1_pd(-INFINITY), tHigh = sHigh, firstSign = zero, signsDiffer = zero;
    const __m256d four = _mm256_set1_pd(4.0), minimumSine = _mm256_set1_pd(kMinimumFootprintSine);
    for (int i = 0; i < 3; ++i) {
        const int j = (i + 1) % 3;
        const __m256d p = _mm256_mul_pd(wx[i], wy[j]), q = _mm256_mul_pd(wy[i], wx[j]);
        const __m256d d = _mm256_sub_pd(p, q), dAbs = _mm256_add_pd(_mm256_andnot_pd(signBit, p), _mm256_andnot_pd(signBit, q));
        ok = _mm256_and_pd(ok, _mm256_and_pd(_mm256_cmp_pd(_mm256_andnot_pd(signBit, d), _mm256_mul_pd(minimumSine, dAbs), _CMP_GE_OQ),
                                             _mm256_cmp_pd(dAbs, zero, _CMP_GT_OQ)));
        // P is bounded only when the three d share a sign: collect the sign bits that differ.
        if (i == 0) firstSign = _mm256_and_pd(d, signBit);
        else signsDiffer = _mm256_or_pd(signsDiffer, _mm256_xor_pd(firstSign, _mm256_and_pd(d, signBit)));
        const __m256d inverse = _mm256_div_pd(_mm256_set1_pd(1.0), d), inverseAbs = _mm256_andnot_pd(signBit, inverse);
        const __m256d a1 = _mm256_mul_pd(c[i], wy[j]), a2 = _mm256_mul_pd(c[j], wy[i]), b1 = _mm256_mul_pd(wx[i], c[j]), b2 = _mm256_mul_pd(wx[j], c[i]);
        const __m256d x = _mm256_mul_pd(_mm256_sub_pd(a2, a1), inverse), y = _mm256_mul_pd(_mm256_sub_pd(b2, b1), inverse);
        auto margin = [&](__m256d numeratorAbs, __m256d v) PENUMBRA_AVX2 {
            const __m256d vAbs = _mm256_andnot_pd(signBit, v);
            const __m256d quotient = _mm256_mul_pd(_mm256_add_pd(numeratorAbs, _mm256_mul_pd(vAbs, dAbs)), inverseAbs);
            return _mm256_mul_pd(_mm256_mul_pd(four, u), _mm256_add_pd(quotient, vAbs));
        };
        const __m256d mx = margin(_mm256_add_pd(_mm256_andnot_pd(signBit, a1), _mm256_andnot_pd(signBit, a2)), x);
        const __m256d my = margin(_mm256_add_pd(_mm256_andnot_pd(signBit, b1), _mm256_andnot_pd(signBit, b2)), y);
        sLow = _mm256_min_pd(sLow, _mm256_sub_pd(x, mx)), sHigh = _mm256_max_pd(sHigh, _mm256_add_pd(x, mx));
        tLow = _mm256_min_pd(tLow, _mm256_sub_pd(y, my)), tHigh = _mm256_max_pd(tHigh, _mm256_add_pd(y, my));
    }
    // Finite ends only (v - v is 0 exactly for finite v; a NaN vertex makes its ends NaN, since
    // min and max return their second operand when either is NaN).
    const __m256d ends[4] = {sLow, sHigh, tLow, tHigh};
    for (const __m256d& v : ends) ok = _mm256_and_pd(ok, _mm256_cmp_pd(_mm256_sub_pd(v, v), zero, _CMP_EQ_OQ));
    const uint32_t lanes = uint32_t(_mm256_movemask_pd(ok)) & ~uint32_t(_mm256_movemask_pd(signsDiffer));
    for (int end = 0; end < 4; ++end) {
        const int axis = end / 2;
        const __m256d bin = _mm256_floor_pd(_mm256_mul_pd(_mm256_sub_pd(ends[end], _mm256_set1_pd(binLow_[axis])), _mm256_set1_pd(binScale_[axis])));
        _mm_storeu_si128(reinterpret_cast<__m128i*>(bins[end]), clampedTruncation(bin, double(kFootprintBins - 1)));
    }
    return lanes;
}

}  // namespace penumbra
