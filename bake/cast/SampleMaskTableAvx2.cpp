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

#include <algorithm>

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

PENUMBRA_AVX2 bool SampleMaskTable::footprintBoxAvx2(const Blocker& b, const glm::dvec3& r, double s, double m, double lo[2],
                                                     double hi[2]) const {
    // footprintBox() with lane e for edge e (lane 3 repeats edge 2) and, after a rotation, lane i
    // for vertex V_i,i+1 (lane 3 repeats V_20). Only the bound matters here, not the rounding
    // order: the margins cover either.
    const __m256d rx = _mm256_set1_pd(r.x), ry = _mm256_set1_pd(r.y), rz = _mm256_set1_pd(r.z), sv = _mm256_set1_pd(s);
    const __m256d signBit = _mm256_set1_pd(-0.0), u = _mm256_set1_pd(kRoundoff);
    const __m256d wx = _mm256_mul_pd(sv, affineAt(b.line, 0, rx, ry, rz));
    const __m256d wy = _mm256_mul_pd(sv, affineAt(b.line, 1, rx, ry, rz));
    const __m256d k = _mm256_mul_pd(sv, affineAt(b.line, 2, rx, ry, rz));
    const __m256d mn = affineAt(b.line, 3, rx, ry, rz);
    const __m256d g = _mm256_add_pd(_mm256_andnot_pd(signBit, wx), _mm256_andnot_pd(signBit, wy));
    const __m256d norm1 = _mm256_add_pd(g, _mm256_andnot_pd(signBit, mn));
    const double fixed = 4096 * kRoundoff * m * m * m;
    const __m256d scaled = _mm256_add_pd(_mm256_set1_pd(fixed), _mm256_mul_pd(norm1, _mm256_set1_pd(flatness_ + 128 * kRoundoff * m)));
    const __m256d slack = _mm256_mul_pd(_mm256_set1_pd(1e-12), _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(radius_), g),
                                                                             _mm256_andnot_pd(signBit, k)));
    const __m256d c = _mm256_add_pd(k, _mm256_mul_pd(_mm256_set1_pd(2.0), _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(2.0), scaled), slack)));
    // The next edge's values in each lane: (1, 2, 0, 0).
    constexpr int kNext = _MM_SHUFFLE(0, 0, 2, 1);
    const __m256d wxj = _mm256_permute4x64_pd(wx, kNext), wyj = _mm256_permute4x64_pd(wy, kNext), cj = _mm256_permute4x64_pd(c, kNext);
    const __m256d p = _mm256_mul_pd(wx, wyj), q = _mm256_mul_pd(wy, wxj);
    const __m256d d = _mm256_sub_pd(p, q), dAbs = _mm256_add_pd(_mm256_andnot_pd(signBit, p), _mm256_andnot_pd(signBit, q));
    const __m256d sure = _mm256_and_pd(_mm256_cmp_pd(_mm256_andnot_pd(signBit, d), _mm256_mul_pd(_mm256_set1_pd(kMinimumFootprintSine), dAbs), _CMP_GE_OQ),
                                       _mm256_cmp_pd(dAbs, _mm256_setzero_pd(), _CMP_GT_OQ));
    const int signs = _mm256_movemask_pd(d);
    if (_mm256_movemask_pd(sure) != 0xF || (signs != 0 && signs != 0xF)) return false;
    const __m256d inverse = _mm256_div_pd(_mm256_set1_pd(1.0), d), inverseAbs = _mm256_andnot_pd(signBit, inverse);
    const __m256d a1 = _mm256_mul_pd(c, wyj), a2 = _mm256_mul_pd(cj, wy), b1 = _mm256_mul_pd(wx, cj), b2 = _mm256_mul_pd(wxj, c);
    const __m256d x = _mm256_mul_pd(_mm256_sub_pd(a2, a1), inverse), y = _mm256_mul_pd(_mm256_sub_pd(b2, b1), inverse);
    const __m256d xAbs = _mm256_andnot_pd(signBit, x), yAbs = _mm256_andnot_pd(signBit, y), four = _mm256_set1_pd(4.0);
    auto margin = [&](__m256d numeratorAbs, __m256d vAbs) PENUMBRA_AVX2 {
        const __m256d quotient = _mm256_mul_pd(_mm256_add_pd(numeratorAbs, _mm256_mul_pd(vAbs, dAbs)), inverseAbs);
        return _mm256_mul_pd(_mm256_mul_pd(four, u), _mm256_add_pd(quotient, vAbs));
    };
    const __m256d mx = margin(_mm256_add_pd(_mm256_andnot_pd(signBit, a1), _mm256_andnot_pd(signBit, a2)), xAbs);
    const __m256d my = margin(_mm256_add_pd(_mm256_andnot_pd(signBit, b1), _mm256_andnot_pd(signBit, b2)), yAbs);
    alignas(32) double xl[4], xh[4], yl[4], yh[4];
    _mm256_store_pd(xl, _mm256_sub_pd(x, mx)), _mm256_store_pd(xh, _mm256_add_pd(x, mx));
    _mm256_store_pd(yl, _mm256_sub_pd(y, my)), _mm256_store_pd(yh, _mm256_add_pd(y, my));
    lo[0] = std::min({xl[0], xl[1], xl[2]}), hi[0] = std::max({xh[0], xh[1], xh[2]});
    lo[1] = std::min({yl[0], yl[1], yl[2]}), hi[1] = std::max({yh[0], yh[1], yh[2]});
    return true;
}

}  // namespace penumbra
