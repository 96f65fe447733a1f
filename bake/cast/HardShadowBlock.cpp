#include "bake/cast/HardShadowBlock.h"

#include "stream/util/Error.h"

#include <immintrin.h>

#include <string>

namespace penumbra {
namespace {

constexpr int kLanes = HardShadowBlock::kLanes;

// ---- scalar: the reference formulation, one lane at a time -------------------------------------

void buildScalar(HardShadowBlock& out, const glm::vec3* samples, int count, double w, const BlockerTriangle& t) {
    for (int i = 0; i < kLanes; ++i) {
        HardShadowVolume h;
        if (i < count) h = makeHardShadowVolume(glm::dvec3(samples[i]), w, t);
        out.side[i] = h.side;
        for (int e = 0; e < 3; ++e) {
            // makeHardShadowVolume leaves the edges unset when side is 0; store zeros then.
            const bool set = h.side != 0.0;
            out.nx[e][i] = set ? h.edge[e].x : 0.0;
            out.ny[e][i] = set ? h.edge[e].y : 0.0;
            out.nz[e][i] = set ? h.edge[e].z : 0.0;
        }
    }
}

uint64_t testScalar(const HardShadowBlock* blocks, uint32_t which, const EdgeOffsets& at, double dist, double eps) {
    uint64_t word = 0;
    for (; which; which &= which - 1) {
        const int b = __builtin_ctz(which);
        const HardShadowBlock& h = blocks[b];
        for (int i = 0; i < kLanes; ++i) {
            bool blocked = h.side[i] * dist > eps;
            for (int e = 0; e < 3 && blocked; ++e) blocked = laneEdgeValue(h, e, i, at) >= 0.0;
            word |= uint64_t(blocked) << (4 * b + i);
        }
    }
    return word;
}

// ---- SSE2: two lanes per register, two registers per block -------------------------------------

uint64_t testSse2(const HardShadowBlock* blocks, uint32_t which, const EdgeOffsets& at, double dist, double eps) {
    __m128d qx[3], qy[3], qz[3];
    for (int e = 0; e < 3; ++e)
        qx[e] = _mm_set1_pd(at.rel[e].x), qy[e] = _mm_set1_pd(at.rel[e].y), qz[e] = _mm_set1_pd(at.rel[e].z);
    const __m128d vd = _mm_set1_pd(dist), ve = _mm_set1_pd(eps), zero = _mm_setzero_pd();
    uint64_t word = 0;
    for (; which; which &= which - 1) {
        const int b = __builtin_ctz(which);
        const HardShadowBlock& h = blocks[b];
        for (int half = 0; half < 2; ++half) {
            const int o = 2 * half;
            __m128d m = _mm_cmpgt_pd(_mm_mul_pd(_mm_load_pd(h.side + o), vd), ve);
            for (int e = 0; e < 3; ++e) {
                __m128d v = _mm_add_pd(_mm_add_pd(_mm_mul_pd(_mm_load_pd(h.nx[e] + o), qx[e]),
                                                  _mm_mul_pd(_mm_load_pd(h.ny[e] + o), qy[e])),
                                       _mm_mul_pd(_mm_load_pd(h.nz[e] + o), qz[e]));
                m = _mm_and_pd(m, _mm_cmpge_pd(v, zero));
            }
            word |= uint64_t(_mm_movemask_pd(m)) << (4 * b + o);
        }
    }
    return word;
}

// ---- AVX2: one block per register ---------------------------------------------------------------
// PENUMBRA_AVX2 (HardShadowBlock.h): AVX2 without FMA, so the rounding is the scalar rule's.

PENUMBRA_AVX2 inline __m256d dot3(__m256d ax, __m256d ay, __m256d az, __m256d bx, __m256d by,
                                                    __m256d bz) {
    return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(ax, bx), _mm256_mul_pd(ay, by)), _mm256_mul_pd(az, bz));
}

PENUMBRA_AVX2 void buildAvx2(HardShadowBlock& out, const glm::vec3* samples, int count, double w,
                                               const BlockerTriangle& t) {
    alignas(32) double px[kLanes], py[kLanes], pz[kLanes];
    for (int i = 0; i < kLanes; ++i) {  // unused lanes repeat a real sample; their side is zeroed
        const glm::vec3& s = samples[i < count ? i : 0];
        px[i] = s.x, py[i] = s.y, pz[i] = s.z;
    }
    const __m256d lx = _mm256_load_pd(px), ly = _mm256_load_pd(py), lz = _mm256_load_pd(pz);
    const __m256d zero = _mm256_setzero_pd(), signBit = _mm256_set1_pd(-0.0), vw = _mm256_set1_pd(w);

    // sl = n . (l - w v0): the side is its sign, negated (0 for a sample in the plane), and the edge
    // normals take its sign.
    const glm::dvec3& v0 = t.v[0];
    const __m256d sl = dot3(_mm256_set1_pd(t.plane.n.x), _mm256_set1_pd(t.plane.n.y), _mm256_set1_pd(t.plane.n.z),
                            _mm256_sub_pd(lx, _mm256_mul_pd(vw, _mm256_set1_pd(v0.x))),
                            _mm256_sub_pd(ly, _mm256_mul_pd(vw, _mm256_set1_pd(v0.y))),
                            _mm256_sub_pd(lz, _mm256_mul_pd(vw, _mm256_set1_pd(v0.z))));
    const __m256d positive = _mm256_cmp_pd(sl, zero, _CMP_GT_OQ);
    const __m256d side = _mm256_or_pd(_mm256_and_pd(positive, _mm256_set1_pd(-1.0)),
                                      _mm256_and_pd(_mm256_cmp_pd(sl, zero, _CMP_LT_OQ), _mm256_set1_pd(1.0)));
    const __m256d live = _mm256_cmp_pd(_mm256_set_pd(3, 2, 1, 0), _mm256_set1_pd(double(count)), _CMP_LT_OQ);
    _mm256_store_pd(out.side, _mm256_and_pd(side, live));

    for (int e = 0; e < 3; ++e) {
        const glm::dvec3& a = t.v[e];
        const glm::dvec3 y = t.v[(e + 1) % 3] - a;
        // x = l - w a, y = b - a; n = cross(x, y) in glm's order, negated where sl < 0.
        const __m256d xx = _mm256_sub_pd(lx, _mm256_mul_pd(vw, _mm256_set1_pd(a.x)));
        const __m256d xy = _mm256_sub_pd(ly, _mm256_mul_pd(vw, _mm256_set1_pd(a.y)));
        const __m256d xz = _mm256_sub_pd(lz, _mm256_mul_pd(vw, _mm256_set1_pd(a.z)));
        const __m256d yx = _mm256_set1_pd(y.x), yy = _mm256_set1_pd(y.y), yz = _mm256_set1_pd(y.z);
        const __m256d nx = _mm256_sub_pd(_mm256_mul_pd(xy, yz), _mm256_mul_pd(yy, xz));
        const __m256d ny = _mm256_sub_pd(_mm256_mul_pd(xz, yx), _mm256_mul_pd(yz, xx));
        const __m256d nz = _mm256_sub_pd(_mm256_mul_pd(xx, yy), _mm256_mul_pd(yx, xy));
        _mm256_store_pd(out.nx[e], _mm256_blendv_pd(_mm256_xor_pd(nx, signBit), nx, positive));
        _mm256_store_pd(out.ny[e], _mm256_blendv_pd(_mm256_xor_pd(ny, signBit), ny, positive));
        _mm256_store_pd(out.nz[e], _mm256_blendv_pd(_mm256_xor_pd(nz, signBit), nz, positive));
    }
}

PENUMBRA_AVX2 uint64_t testAvx2(const HardShadowBlock* blocks, uint32_t which, const EdgeOffsets& at,
                                                  double dist, double eps) {
    __m256d qx[3], qy[3], qz[3];
    for (int e = 0; e < 3; ++e)
        qx[e] = _mm256_set1_pd(at.rel[e].x), qy[e] = _mm256_set1_pd(at.rel[e].y), qz[e] = _mm256_set1_pd(at.rel[e].z);
    const __m256d vd = _mm256_set1_pd(dist), ve = _mm256_set1_pd(eps), zero = _mm256_setzero_pd();
    uint64_t word = 0;
    for (; which; which &= which - 1) {
        const int b = __builtin_ctz(which);
        const HardShadowBlock& h = blocks[b];
        __m256d m = _mm256_cmp_pd(_mm256_mul_pd(_mm256_load_pd(h.side), vd), ve, _CMP_GT_OQ);
        for (int e = 0; e < 3; ++e) {
            __m256d v = dot3(_mm256_load_pd(h.nx[e]), _mm256_load_pd(h.ny[e]), _mm256_load_pd(h.nz[e]), qx[e], qy[e], qz[e]);
            m = _mm256_and_pd(m, _mm256_cmp_pd(v, zero, _CMP_GE_OQ));
        }
        word |= uint64_t(_mm256_movemask_pd(m)) << (4 * b);
    }
    return word;
}

}  // namespace

bool simdSupported(SimdLevel level) {
    switch (level) {
        case SimdLevel::Scalar:
        case SimdLevel::Sse2:  // part of x86-64
        case SimdLevel::Auto: return true;
        case SimdLevel::Avx2: return __builtin_cpu_supports("avx2");
    }
    return false;
}

HardShadowKernels hardShadowKernels(SimdLevel level) {
    if (level == SimdLevel::Auto) level = simdSupported(SimdLevel::Avx2) ? SimdLevel::Avx2 : SimdLevel::Sse2;
    if (!simdSupported(level)) fail("--simd", "{} is not supported by this CPU", simdName(level));
    switch (level) {
        case SimdLevel::Avx2: return {level, buildAvx2, testAvx2};
        case SimdLevel::Sse2: return {level, buildScalar, testSse2};  // the build is scalar: SSE2 lacks blendv
        default: return {SimdLevel::Scalar, buildScalar, testScalar};
    }
}

const char* simdName(SimdLevel level) {
    switch (level) {
        case SimdLevel::Scalar: return "scalar";
        case SimdLevel::Sse2: return "sse2";
        case SimdLevel::Avx2: return "avx2";
        case SimdLevel::Auto: return "auto";
    }
    return "?";
}

SimdLevel parseSimdLevel(std::string_view name, std::string_view where) {
    for (SimdLevel l : {SimdLevel::Scalar, SimdLevel::Sse2, SimdLevel::Avx2, SimdLevel::Auto})
        if (name == simdName(l)) return l;
    fail(std::string(where), "unknown SIMD level '{}' (expected scalar, sse2, avx2 or auto)", name);
}

}  // namespace penumbra
