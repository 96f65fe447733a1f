/// @file LeafPrefilterAvx2.cpp
/// @brief leafPrefilterAvx2(): LeafPrefilter.h's tests for four receivers per instruction.

#include "bake/cast/LeafPrefilter.h"

#include <immintrin.h>

namespace penumbra {

PENUMBRA_AVX2 uint32_t leafPrefilterAvx2(const PenumbraVolume& v, uint32_t planes, const BlockerTriangle& t,
                                         const glm::dvec3* p, const double* epsilons, int count, double dist[4]) {
    // Missing lanes repeat receiver 0 and are masked off at the end.
    const int i1 = count > 1 ? 1 : 0, i2 = count > 2 ? 2 : 0, i3 = count > 3 ? 3 : 0;
    const __m256d px = _mm256_setr_pd(p[0].x, p[i1].x, p[i2].x, p[i3].x);
    const __m256d py = _mm256_setr_pd(p[0].y, p[i1].y, p[i2].y, p[i3].y);
    const __m256d pz = _mm256_setr_pd(p[0].z, p[i1].z, p[i2].z, p[i3].z);
    const __m256d zero = _mm256_setzero_pd();
    const uint32_t lanes = (1u << count) - 1u;
    uint32_t inside = lanes;
    // contains(): ((nx px + ny py) + nz pz) + d < 0 puts a receiver outside, plane by plane.
    for (uint32_t bits = planes & v.all(); bits && inside; bits &= bits - 1) {
        const int j = __builtin_ctz(bits);
        const __m256d value = _mm256_add_pd(
            _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(v.nx[j]), px), _mm256_mul_pd(_mm256_set1_pd(v.ny[j]), py)),
                          _mm256_mul_pd(_mm256_set1_pd(v.nz[j]), pz)),
            _mm256_set1_pd(v.d[j]));
        inside &= ~uint32_t(_mm256_movemask_pd(_mm256_cmp_pd(value, zero, _CMP_LT_OQ)));
    }
    if (!inside) return 0;
    // distanceBehind(): glm::dot(n, p - v0), its products summed left to right.
    const __m256d dx = _mm256_mul_pd(_mm256_set1_pd(t.plane.n.x), _mm256_sub_pd(px, _mm256_set1_pd(t.v[0].x)));
    const __m256d dy = _mm256_mul_pd(_mm256_set1_pd(t.plane.n.y), _mm256_sub_pd(py, _mm256_set1_pd(t.v[0].y)));
    const __m256d dz = _mm256_mul_pd(_mm256_set1_pd(t.plane.n.z), _mm256_sub_pd(pz, _mm256_set1_pd(t.v[0].z)));
    const __m256d d = _mm256_add_pd(_mm256_add_pd(dx, dy), dz);
    const __m256d eps = _mm256_setr_pd(epsilons[0], epsilons[i1], epsilons[i2], epsilons[i3]);
    const __m256d negD = _mm256_xor_pd(d, _mm256_set1_pd(-0.0));
    const uint32_t behind = uint32_t(_mm256_movemask_pd(_mm256_cmp_pd(d, eps, _CMP_GT_OQ)));
    const uint32_t front = uint32_t(_mm256_movemask_pd(_mm256_cmp_pd(negD, eps, _CMP_GT_OQ)));
    _mm256_storeu_pd(dist, d);
    return inside & (t.closed ? front & ~behind : behind | front);
}

}  // namespace penumbra
