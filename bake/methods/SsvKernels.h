#pragma once
/// @file SsvKernels.h
/// @brief The per-sample loops of `--method ssv` (SsvCaster.h): integrating one silhouette edge
/// into the depth complexity of a run of light samples, and testing a straddling triangle
/// against them. Both evaluate the blocking rule's own double expressions in the rule's operation
/// order (BlockingRule.h), without fused multiply-adds, so every decision is the rule's; they are
/// compiled for AVX2 and for the baseline, chosen at run time, with identical bits.

#include "bake/rule/BlockingRule.h"

#include <cstdint>

namespace penumbra {

/// @brief One edge (a, b) of a triangle that may block the receiver r, for one reference sample l0.
struct SsvEdgeTerm {
    glm::dvec3 wa, ba, ra;  ///< w a, b - a, r - a: the rule's operands
    double s = 1;           ///< the triangle's side of the light: the rule's s for every sample
    glm::dvec3 qa, qb;      ///< a's and b's side of the plane (r, l0, l) is dot(q, l - w r) > 0
    int refInside = 0;      ///< [E(l0) >= 0]
};

/// @brief The rule's edge value at sample l: s * dot(cross(l - w a, b - a), r - a). Its sign is the
/// sign edgeValue(makeHardShadowVolume(l, w, t), t, e, r) has (the rule multiplies s in first;
/// s = +-1 commutes with rounding).
inline double ssvEdgeValue(const SsvEdgeTerm& t, double lx, double ly, double lz) {
    const double x = lx - t.wa.x, y = ly - t.wa.y, z = lz - t.wa.z;
    const double cx = y * t.ba.z - t.ba.y * z, cy = z * t.ba.x - t.ba.z * x, cz = x * t.ba.y - t.ba.x * y;
    return t.s * (cx * t.ra.x + cy * t.ra.y + cz * t.ra.z);
}

/// @brief depth[j] += [a, b separated by the plane (r, l0, l_j)] ([E(l_j) >= 0] - [E(l0) >= 0])
/// for the @p n samples l_j = (lx, ly, lz)[j], with d_j = l_j - w r given as (dx, dy, dz)[j].
void ssvIntegrateSamples(const SsvEdgeTerm& t, uint32_t n, const double* lx, const double* ly, const double* lz,
                         const double* dx, const double* dy, const double* dz, int* depth);

/// @brief blocked[j] |= the rule's blocks(l_j, w, r, t, eps) for the @p n samples l_j.
/// @param distance distanceBehind(t, r)
void ssvStraddlerSamples(const BlockerTriangle& t, double w, const glm::dvec3& r, double distance, double eps, uint32_t n,
                         const double* lx, const double* ly, const double* lz, uint8_t* blocked);

}  // namespace penumbra
