#pragma once
/// @file PenumbraVolume.h
/// @brief Penumbra volumes V_L and V_Gk (Laine & Aila 2005, Section 3.2) with active plane sets
/// (optimization B).

#include "bake/cast/SimdLevel.h"
#include "bake/rule/BlockingRule.h"
#include "bake/rule/ConvexBound.h"
#include "bake/rule/Plane.h"

#include <cstdint>

#include <emmintrin.h>

namespace penumbra {

/// @brief The region that triangle T can shadow from a convex light (or sample-group) bound:
/// the intersection of the positive sides of the separating planes between the bound and T,
/// capped by T's plane when that plane does not cut the bound.
///
/// Every plane is pushed outward by a small scale-relative margin, so the volume contains every
/// receiver that the exact blocking rule (BlockingRule.h) says is blocked, despite roundoff.
/// A volume with no planes is all of space (the bound and T touch).
///
/// Planes are stored as structure of arrays so that box and point tests take two planes per
/// SSE2 instruction (x86-64 baseline, no dispatch). The slot after the last plane is kept
/// zeroed, so a pair load never reads an unset value.
struct alignas(16) PenumbraVolume {
    static constexpr int kMaxPlanes = 32;
    // Left uninitialised on purpose (see Plane): volumes are built per triangle and per group.
    double nx[kMaxPlanes], ny[kMaxPlanes], nz[kMaxPlanes], d[kMaxPlanes];
    int count = 0;
    /// V_L of a closed face only: a plane culls every receiver box in front of T (BlockerBatch.h,
    /// cutInFront()), so the traversal needs no test of its own for it.
    bool frontCulled = false;

    /// The active-plane set with every plane active ("ALL" in the paper's pseudocode).
    uint32_t all() const { return count >= 32 ? ~0u : (1u << count) - 1u; }
    Plane plane(int i) const { return {{nx[i], ny[i], nz[i]}, d[i]}; }
    /// Appends @p p; the caller checks count < kMaxPlanes.
    void push(const Plane& p) {
        nx[count] = p.n.x, ny[count] = p.n.y, nz[count] = p.n.z, d[count] = p.d;
        ++count;
        if (count < kMaxPlanes) nx[count] = ny[count] = nz[count] = d[count] = 0.0;
    }
};

/// @brief Builds the penumbra volume of @p bound and the (valid) triangle @p t into @p out
/// (in place: a volume is a kilobyte, and the caster builds several per triangle).
/// @param cull when given, building stops as soon as one accepted plane leaves this box
/// entirely outside: T shadows nothing in it, and most of the volume need not be built.
/// @param level Avx2 evaluates the candidate planes four at a time (PenumbraVolumeAvx2.cpp), any
/// other level one at a time; both give the same planes in the same order, bit for bit. The
/// caller resolves Auto (HardShadowKernels::level) and checks that the CPU has AVX2.
/// @return false when building stopped that way (@p out is then incomplete and unusable).
bool buildPenumbraVolume(const ConvexBound& bound, const BlockerTriangle& t, PenumbraVolume& out,
                         const Box* cull = nullptr, SimdLevel level = SimdLevel::Scalar);

/// @brief Convenience form of buildPenumbraVolume().
PenumbraVolume makePenumbraVolume(const ConvexBound& bound, const BlockerTriangle& t);

/// @brief INTERSECTS(B_N, V, P, P'): false when @p box is entirely outside one active plane;
/// otherwise clears from @p active the planes the box is entirely inside of.
/// A plane's value at the box corner farthest along (nearest against) its normal is the sum of
/// the per-axis maxima (minima) of n_i * lo_i and n_i * hi_i: the corner selection of classify()
/// without branches.
inline bool intersects(const PenumbraVolume& volume, const Box& box, uint32_t& active) {
    const __m128d lx = _mm_set1_pd(box.lo.x), ly = _mm_set1_pd(box.lo.y), lz = _mm_set1_pd(box.lo.z);
    const __m128d hx = _mm_set1_pd(box.hi.x), hy = _mm_set1_pd(box.hi.y), hz = _mm_set1_pd(box.hi.z);
    const __m128d zero = _mm_setzero_pd();
    for (uint32_t bits = active; bits;) {
        const int j = __builtin_ctz(bits) & ~1;
        const uint32_t pair = (active >> j) & 3u;
        bits &= ~(3u << j);
        const __m128d nx = _mm_load_pd(volume.nx + j), ny = _mm_load_pd(volume.ny + j), nz = _mm_load_pd(volume.nz + j);
        const __m128d ax = _mm_mul_pd(nx, lx), bx = _mm_mul_pd(nx, hx);
        const __m128d ay = _mm_mul_pd(ny, ly), by = _mm_mul_pd(ny, hy);
        const __m128d az = _mm_mul_pd(nz, lz), bz = _mm_mul_pd(nz, hz);
        const __m128d d = _mm_load_pd(volume.d + j);
        const __m128d far =
            _mm_add_pd(_mm_add_pd(_mm_add_pd(_mm_max_pd(ax, bx), _mm_max_pd(ay, by)), _mm_max_pd(az, bz)), d);
        if (uint32_t(_mm_movemask_pd(_mm_cmplt_pd(far, zero))) & pair) return false;
        const __m128d near =
            _mm_add_pd(_mm_add_pd(_mm_add_pd(_mm_min_pd(ax, bx), _mm_min_pd(ay, by)), _mm_min_pd(az, bz)), d);
        active &= ~((uint32_t(_mm_movemask_pd(_mm_cmpge_pd(near, zero))) & pair) << j);
    }
    return true;
}

/// @brief intersects() four planes per instruction (BoxTestAvx2.cpp): the same answer and the
/// same @p active, bit for bit. Only for a CPU with AVX2 (the caller checks its SimdLevel).
PENUMBRA_AVX2 bool intersectsAvx2(const PenumbraVolume& volume, const Box& box, uint32_t& active);

/// @brief POINT-IN-VOLUME(r, V, P): the point is on the positive side of every active plane.
inline bool contains(const PenumbraVolume& volume, const glm::dvec3& p, uint32_t active) {
    const __m128d px = _mm_set1_pd(p.x), py = _mm_set1_pd(p.y), pz = _mm_set1_pd(p.z);
    for (uint32_t bits = active; bits;) {
        const int j = __builtin_ctz(bits) & ~1;
        const uint32_t pair = (active >> j) & 3u;
        bits &= ~(3u << j);
        const __m128d v = _mm_add_pd(_mm_add_pd(_mm_add_pd(_mm_mul_pd(_mm_load_pd(volume.nx + j), px),
                                                           _mm_mul_pd(_mm_load_pd(volume.ny + j), py)),
                                                _mm_mul_pd(_mm_load_pd(volume.nz + j), pz)),
                                     _mm_load_pd(volume.d + j));
        if (uint32_t(_mm_movemask_pd(_mm_cmplt_pd(v, _mm_setzero_pd()))) & pair) return false;
    }
    return true;
}

}  // namespace penumbra
