/// @file BoxTestAvx2.cpp
/// @brief intersectsAvx2(): the traversal's box test against a penumbra volume, four planes per
/// instruction instead of intersects()'s two.
///
/// Lanes run intersects()'s operations in its order (products, per-axis maxima and minima, summed
/// x, then y, then z, then d), so every plane gives the same far and near values and the same
/// answer and active set come out. Both forms test every initially active plane and stop at the
/// first block of planes with one outside; the planes of a block are only cleared after it is
/// tested, so the grouping by two or by four changes nothing.

#include "bake/cast/PenumbraVolume.h"

#include <immintrin.h>

namespace penumbra {

PENUMBRA_AVX2 bool intersectsAvx2(const PenumbraVolume& volume, const Box& box, uint32_t& active) {
    const __m256d lx = _mm256_set1_pd(box.lo.x), ly = _mm256_set1_pd(box.lo.y), lz = _mm256_set1_pd(box.lo.z);
    const __m256d hx = _mm256_set1_pd(box.hi.x), hy = _mm256_set1_pd(box.hi.y), hz = _mm256_set1_pd(box.hi.z);
    const __m256d zero = _mm256_setzero_pd();
    for (uint32_t bits = active; bits;) {
        // Lanes past the volume's planes read whatever the arrays hold; `quad` masks them out.
        const int j = __builtin_ctz(bits) & ~3;
        const uint32_t quad = (active >> j) & 15u;
        bits &= ~(15u << j);
        const __m256d nx = _mm256_loadu_pd(volume.nx + j), ny = _mm256_loadu_pd(volume.ny + j),
                      nz = _mm256_loadu_pd(volume.nz + j);
        const __m256d ax = _mm256_mul_pd(nx, lx), bx = _mm256_mul_pd(nx, hx);
        const __m256d ay = _mm256_mul_pd(ny, ly), by = _mm256_mul_pd(ny, hy);
        const __m256d az = _mm256_mul_pd(nz, lz), bz = _mm256_mul_pd(nz, hz);
        const __m256d d = _mm256_loadu_pd(volume.d + j);
        const __m256d far = _mm256_add_pd(
            _mm256_add_pd(_mm256_add_pd(_mm256_max_pd(ax, bx), _mm256_max_pd(ay, by)), _mm256_max_pd(az, bz)), d);
        if (uint32_t(_mm256_movemask_pd(_mm256_cmp_pd(far, zero, _CMP_LT_OQ))) & quad) return false;
        const __m256d near = _mm256_add_pd(
            _mm256_add_pd(_mm256_add_pd(_mm256_min_pd(ax, bx), _mm256_min_pd(ay, by)), _mm256_min_pd(az, bz)), d);
        active &= ~((uint32_t(_mm256_movemask_pd(_mm256_cmp_pd(near, zero, _CMP_GE_OQ))) & quad) << j);
    }
    return true;
}

}  // namespace penumbra
