/// @file PenumbraVolumeAvx2.cpp
/// @brief addCandidatesAvx2(): a penumbra volume's candidate planes four at a time.
///
/// Family 1 puts four bound vertices in the lanes (one edge of T each pass), family 2 T's three
/// vertices (one bound edge each pass). Every lane runs the scalar tryPlane()'s operations in its
/// order without FMA (glm's cross product, dot products summed (x + y) + z), evaluates every
/// point the scalar code would and masks the ones it skips, so the same candidates pass with the
/// same normals; the accepted ones are normalised in the lanes as Builder::accept() does and added
/// in the scalar order through Builder::add(). Measured: 1,290-2,000 cycles per build in scalar
/// form, 780-1,070 in this one (docs/performance.md, "Volume builds and the traversal").

#include "bake/cast/PenumbraVolumeBuilder.h"

#include <immintrin.h>

#include <algorithm>
#include <array>
#include <vector>

namespace penumbra::volume_detail {
namespace {

struct Lanes {
    __m256d x, y, z;
};

PENUMBRA_AVX2 inline Lanes broadcast(const glm::dvec3& v) { return {_mm256_set1_pd(v.x), _mm256_set1_pd(v.y), _mm256_set1_pd(v.z)}; }

/// glm::cross(a, b): (a.y b.z - b.y a.z, a.z b.x - b.z a.x, a.x b.y - b.x a.y).
PENUMBRA_AVX2 inline Lanes cross(const Lanes& a, const Lanes& b) {
    return {_mm256_sub_pd(_mm256_mul_pd(a.y, b.z), _mm256_mul_pd(b.y, a.z)),
            _mm256_sub_pd(_mm256_mul_pd(a.z, b.x), _mm256_mul_pd(b.z, a.x)),
            _mm256_sub_pd(_mm256_mul_pd(a.x, b.y), _mm256_mul_pd(b.x, a.y))};
}

/// glm::dot(a, b): (a.x b.x + a.y b.y) + a.z b.z.
PENUMBRA_AVX2 inline __m256d dot(const Lanes& a, const Lanes& b) {
    return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(a.x, b.x), _mm256_mul_pd(a.y, b.y)), _mm256_mul_pd(a.z, b.z));
}

/// b - w a, lane by lane, as glm computes `b - w * a`.
PENUMBRA_AVX2 inline Lanes minusScaled(const Lanes& b, __m256d w, const Lanes& a) {
    return {_mm256_sub_pd(b.x, _mm256_mul_pd(w, a.x)), _mm256_sub_pd(b.y, _mm256_mul_pd(w, a.y)),
            _mm256_sub_pd(b.z, _mm256_mul_pd(w, a.z))};
}

PENUMBRA_AVX2 inline __m256d absolute(__m256d v) { return _mm256_andnot_pd(_mm256_set1_pd(-0.0), v); }

/// Lanes where a bound vertex at @p x (already signed by s) puts the candidate out: on T's side
/// beyond the tolerance.
PENUMBRA_AVX2 inline uint32_t beyond(__m256d x, __m256d tolerance) {
    const __m256d out = _mm256_and_pd(_mm256_cmp_pd(x, _mm256_setzero_pd(), _CMP_GT_OQ),
                                      _mm256_cmp_pd(_mm256_mul_pd(x, x), tolerance, _CMP_GT_OQ));
    return uint32_t(_mm256_movemask_pd(out));
}

/// The lanes whose |n|^2 is positive and finite, as tryPlane() requires.
PENUMBRA_AVX2 inline uint32_t usable(__m256d nn) {
    return uint32_t(_mm256_movemask_pd(_mm256_and_pd(_mm256_cmp_pd(nn, _mm256_setzero_pd(), _CMP_GT_OQ),
                                                     _mm256_cmp_pd(nn, _mm256_set1_pd(INFINITY), _CMP_LT_OQ))));
}

/// Four points, one per lane.
PENUMBRA_AVX2 inline Lanes lanes(const glm::dvec3* d) {
    return {_mm256_setr_pd(d[0].x, d[1].x, d[2].x, d[3].x), _mm256_setr_pd(d[0].y, d[1].y, d[2].y, d[3].y),
            _mm256_setr_pd(d[0].z, d[1].z, d[2].z, d[3].z)};
}

/// Lanes where a vertex of T at @p e lies on the bound's side beyond the tolerance: s e < 0 and
/// e^2 > tol2.
PENUMBRA_AVX2 inline uint32_t againstBound(__m256d e, __m256d s, __m256d tol2) {
    const __m256d out = _mm256_and_pd(_mm256_cmp_pd(_mm256_mul_pd(s, e), _mm256_setzero_pd(), _CMP_LT_OQ),
                                      _mm256_cmp_pd(_mm256_mul_pd(e, e), tol2, _CMP_GT_OQ));
    return uint32_t(_mm256_movemask_pd(out));
}

/// The lanes whose candidate @p n (orientation @p s) bound vertex @p j, at @p d = b_j - w anchor, puts out.
PENUMBRA_AVX2 inline uint32_t boundVertexRejects(const Builder& b, size_t j, const Lanes& n, __m256d s, const Lanes& d,
                                                  __m256d tol2) {
    const __m256d x = _mm256_mul_pd(s, dot(n, d));
    const __m256d tolerance = b.bound.w == 0.0 ? _mm256_mul_pd(tol2, _mm256_set1_pd(b.boundTolerance2[j])) : tol2;
    return beyond(x, tolerance);
}

/// Adds the accepted lanes of a pass in lane order, stopping once the builder is culled. The
/// normalisation runs in the lanes as Builder::accept() computes it: unit = n (s / sqrt(nn)),
/// d = -dot(unit, anchor) (square root and division are correctly rounded in both forms).
PENUMBRA_AVX2 void acceptLanes(Builder& b, uint32_t accepted, const Lanes& n, __m256d nn, __m256d s, const Lanes& anchor) {
    if (!accepted) return;
    const __m256d factor = _mm256_div_pd(s, _mm256_sqrt_pd(nn));
    const Lanes unit{_mm256_mul_pd(n.x, factor), _mm256_mul_pd(n.y, factor), _mm256_mul_pd(n.z, factor)};
    const __m256d d = _mm256_xor_pd(dot(unit, anchor), _mm256_set1_pd(-0.0));
    alignas(32) double ux[4], uy[4], uz[4], ud[4];
    _mm256_store_pd(ux, unit.x), _mm256_store_pd(uy, unit.y), _mm256_store_pd(uz, unit.z), _mm256_store_pd(ud, d);
    // The adds below are scalar: leave no dirty upper halves to the SSE code they may reach.
    _mm256_zeroupper();
    for (; accepted && !b.culled; accepted &= accepted - 1) {
        const int l = __builtin_ctz(accepted);
        b.add(Plane{{ux[l], uy[l], uz[l]}, ud[l]});
    }
}

/// Family 1: through T's edge (a, c) and bound vertices i0..i0+3 (lanes past the last unused).
PENUMBRA_AVX2 void edgeVertexPass(Builder& b, int e, size_t i0) {
    const std::vector<glm::dvec3>& vertices = b.bound.vertices;
    const size_t count = std::min<size_t>(4, vertices.size() - i0);
    const glm::dvec3& a = b.t.v[e];
    const glm::dvec3& c = b.t.v[(e + 1) % 3];
    const glm::dvec3& third = b.t.v[(e + 2) % 3];
    glm::dvec3 chunk[4];  // lanes past the last bound vertex repeat the first and are masked off
    for (size_t l = 0; l < 4; ++l) chunk[l] = vertices[i0 + (l < count ? l : 0)];
    const Lanes bi = lanes(chunk);
    const __m256d w = _mm256_set1_pd(b.bound.w);
    const Lanes n = cross(broadcast(c - a), minusScaled(bi, w, broadcast(a)));
    const __m256d nn = dot(n, n), tol2 = _mm256_mul_pd(_mm256_set1_pd(b.tolerancePrefix()), nn);
    // Only the third vertex of T is off the plane, so it alone orients it (and never rejects).
    const __m256d off = dot(n, broadcast(third - a));
    const __m256d s = _mm256_blendv_pd(_mm256_set1_pd(1.0), _mm256_set1_pd(-1.0), _mm256_cmp_pd(off, _mm256_setzero_pd(), _CMP_LT_OQ));
    uint32_t live = usable(nn) & ((1u << count) - 1u);
    for (size_t j = 0; j < vertices.size() && live; ++j) {
        // Lane l is the candidate through vertex i0 + l, which it does not evaluate.
        const uint32_t self = j >= i0 && j < i0 + count ? 1u << (j - i0) : 0u;
        live &= ~(boundVertexRejects(b, j, n, s, broadcast(vertices[j] - b.bound.w * a), tol2) & ~self);
    }
    acceptLanes(b, live, n, nn, s, broadcast(a));
}

/// Family 2: through the bound edge (p, q) and each of T's vertices (lanes 0-2).
PENUMBRA_AVX2 void boundEdgePass(Builder& b, const std::array<int, 2>& edge) {
    const std::vector<glm::dvec3>& vertices = b.bound.vertices;
    const glm::dvec3* v = b.t.v;
    const glm::dvec3& p = vertices[size_t(edge[0])];
    const glm::dvec3 along = vertices[size_t(edge[1])] - p;
    const glm::dvec3 corners[4] = {v[0], v[1], v[2], v[0]};  // lane 3 repeats vertex 0, masked off
    const Lanes tv = lanes(corners);
    const __m256d w = _mm256_set1_pd(b.bound.w);
    const Lanes n = cross(minusScaled(broadcast(p), w, tv), broadcast(along));
    const __m256d nn = dot(n, n), tol2 = _mm256_mul_pd(_mm256_set1_pd(b.tolerancePrefix()), nn);
    // Lane i's other two vertices of T, in index order: (1, 2), (0, 2), (0, 1).
    const glm::dvec3 first[4] = {v[1] - v[0], v[0] - v[1], v[0] - v[2], v[1] - v[0]};
    const glm::dvec3 second[4] = {v[2] - v[0], v[2] - v[1], v[1] - v[2], v[2] - v[0]};
    const __m256d ea = dot(n, lanes(first)), eb = dot(n, lanes(second));
    // far: the first of the two whose |e| exceeds the one before (0 when neither is off the plane).
    const __m256d zero = _mm256_setzero_pd();
    const __m256d farA = _mm256_blendv_pd(zero, ea, _mm256_cmp_pd(absolute(ea), zero, _CMP_GT_OQ));
    const __m256d far = _mm256_blendv_pd(farA, eb, _mm256_cmp_pd(absolute(eb), absolute(farA), _CMP_GT_OQ));
    const __m256d s = _mm256_blendv_pd(_mm256_set1_pd(1.0), _mm256_set1_pd(-1.0), _mm256_cmp_pd(far, zero, _CMP_LT_OQ));
    uint32_t live = usable(nn) & 7u & ~againstBound(ea, s, tol2) & ~againstBound(eb, s, tol2);
    for (size_t j = 0; j < vertices.size() && live; ++j) {
        if (int(j) == edge[0] || int(j) == edge[1]) continue;
        live &= ~boundVertexRejects(b, j, n, s, minusScaled(broadcast(vertices[j]), w, tv), tol2);
    }
    acceptLanes(b, live, n, nn, s, tv);
}

}  // namespace

PENUMBRA_AVX2 void addCandidatesAvx2(Builder& b) {
    for (int e = 0; e < 3 && !b.culled; ++e)
        for (size_t i0 = 0; i0 < b.bound.vertices.size() && !b.culled; i0 += 4) edgeVertexPass(b, e, i0);
    for (size_t k = 0; k < b.bound.edges.size() && !b.culled; ++k) boundEdgePass(b, b.bound.edges[k]);
}

}  // namespace penumbra::volume_detail
