#pragma once
/// @file PenumbraVolume.h
/// @brief Penumbra volumes V_L and V_Gk (Laine & Aila 2005, Section 3.2) with active plane sets
/// (optimization B).

#include "bake/BlockingRule.h"
#include "bake/ConvexBound.h"
#include "bake/Plane.h"

#include <cstdint>

namespace penumbra {

/// @brief The region that triangle T can shadow from a convex light (or sample-group) bound:
/// the intersection of the positive sides of the separating planes between the bound and T,
/// capped by T's plane when that plane does not cut the bound.
///
/// Every plane is pushed outward by a small scale-relative margin, so the volume contains every
/// receiver that the exact blocking rule (BlockingRule.h) says is blocked, despite roundoff.
/// A volume with no planes is all of space (the bound and T touch).
struct PenumbraVolume {
    static constexpr int kMaxPlanes = 32;
    Plane planes[kMaxPlanes];
    int count = 0;

    /// The active-plane set with every plane active ("ALL" in the paper's pseudocode).
    uint32_t all() const { return count >= 32 ? ~0u : (1u << count) - 1u; }
};

/// @brief Builds the penumbra volume of @p bound and the (valid) triangle @p t.
PenumbraVolume makePenumbraVolume(const ConvexBound& bound, const BlockerTriangle& t);

/// @brief INTERSECTS(B_N, V, P, P'): false when @p box is entirely outside one active plane;
/// otherwise clears from @p active the planes the box is entirely inside of.
inline bool intersects(const PenumbraVolume& volume, const Box& box, uint32_t& active) {
    for (uint32_t bits = active; bits; bits &= bits - 1) {
        int i = __builtin_ctz(bits);
        switch (classify(volume.planes[i], box)) {
            case BoxSide::Outside: return false;
            case BoxSide::Inside: active &= ~(1u << i); break;
            case BoxSide::Straddles: break;
        }
    }
    return true;
}

/// @brief POINT-IN-VOLUME(r, V, P): the point is on the positive side of every active plane.
inline bool contains(const PenumbraVolume& volume, const glm::dvec3& p, uint32_t active) {
    for (uint32_t bits = active; bits; bits &= bits - 1)
        if (volume.planes[__builtin_ctz(bits)].eval(p) < 0.0) return false;
    return true;
}

}  // namespace penumbra
