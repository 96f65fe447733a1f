/// @file OutlineTestAvx2.cpp
/// @brief outlineLanesAvx2(): OutlineTest.h's four-lane alpha test.

#include "bake/cast/OutlineTest.h"
#include "bake/cast/SimdLevel.h"

#include <immintrin.h>

namespace penumbra {
namespace {

/// laneEdgeValue() for four lanes: (nx q.x + ny q.y) + nz q.z.
PENUMBRA_AVX2 inline __m256d edgeValues(const HardShadowBlock& h, int e, const glm::dvec3& q) {
    const __m256d x = _mm256_mul_pd(_mm256_load_pd(h.nx[e]), _mm256_set1_pd(q.x));
    const __m256d y = _mm256_mul_pd(_mm256_load_pd(h.ny[e]), _mm256_set1_pd(q.y));
    const __m256d z = _mm256_mul_pd(_mm256_load_pd(h.nz[e]), _mm256_set1_pd(q.z));
    return _mm256_add_pd(_mm256_add_pd(x, y), z);
}

/// (b0 c0 + b1 c1) + b2 c2, lookup()'s barycentric mix of one UV coordinate.
PENUMBRA_AVX2 inline __m256d mix(__m256d b0, __m256d b1, __m256d b2, double c0, double c1, double c2) {
    return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(b0, _mm256_set1_pd(c0)), _mm256_mul_pd(b1, _mm256_set1_pd(c1))),
                         _mm256_mul_pd(b2, _mm256_set1_pd(c2)));
}

/// (t0 u + t1 v) + t2, one row of the map's transform.
PENUMBRA_AVX2 inline __m256d affine(__m256d u, __m256d v, double t0, double t1, double t2) {
    return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(t0), u), _mm256_mul_pd(_mm256_set1_pd(t1), v)),
                         _mm256_set1_pd(t2));
}

}  // namespace

PENUMBRA_AVX2 uint32_t outlineLanesAvx2(const HardShadowBlock& h, uint32_t lanes, const EdgeOffsets& at, const AlphaOutline& o) {
    const __m256d e0 = edgeValues(h, 0, at.rel[0]), e1 = edgeValues(h, 1, at.rel[1]), e2 = edgeValues(h, 2, at.rel[2]);
    // barycentricsAtEdges(): b0 = E_1 / sum, b1 = E_2 / sum, b2 = E_0 / sum; the centroid unless sum > 0.
    const __m256d sum = _mm256_add_pd(_mm256_add_pd(e0, e1), e2);
    const __m256d positive = _mm256_cmp_pd(sum, _mm256_setzero_pd(), _CMP_GT_OQ);
    const __m256d third = _mm256_set1_pd(1.0 / 3.0);
    const __m256d b0 = _mm256_blendv_pd(third, _mm256_div_pd(e1, sum), positive);
    const __m256d b1 = _mm256_blendv_pd(third, _mm256_div_pd(e2, sum), positive);
    const __m256d b2 = _mm256_blendv_pd(third, _mm256_div_pd(e0, sum), positive);
    // lookup(): the corners' UV mixed, then the map's transform.
    const __m256d u0 = mix(b0, b1, b2, o.uv[0].x, o.uv[1].x, o.uv[2].x);
    const __m256d v0 = mix(b0, b1, b2, o.uv[0].y, o.uv[1].y, o.uv[2].y);
    const std::array<double, 6>& t = o.transform;
    const __m256d u = affine(u0, v0, t[0], t[1], t[2]), v = affine(u0, v0, t[3], t[4], t[5]);
    const __m256d one = _mm256_set1_pd(1.0), two = _mm256_set1_pd(2.0);
    __m256d f;
    if (o.shape == AlphaShape::Leaf) {  // 4u(1 - u) - |2v - 1|
        const __m256d bend = _mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(4.0), u), _mm256_sub_pd(one, u));
        const __m256d offset = _mm256_andnot_pd(_mm256_set1_pd(-0.0), _mm256_sub_pd(_mm256_mul_pd(two, v), one));
        f = _mm256_sub_pd(bend, offset);
    } else {  // petal: 1 - (x^2 + y^2), x = 2u - 1, y = 2v - 1
        const __m256d x = _mm256_sub_pd(_mm256_mul_pd(two, u), one), y = _mm256_sub_pd(_mm256_mul_pd(two, v), one);
        f = _mm256_sub_pd(one, _mm256_add_pd(_mm256_mul_pd(x, x), _mm256_mul_pd(y, y)));
    }
    return lanes & uint32_t(_mm256_movemask_pd(_mm256_cmp_pd(f, _mm256_setzero_pd(), _CMP_GT_OQ)));
}

}  // namespace penumbra
