#pragma once
// Exactness for generated scenes: hierarchical penumbra casting with every optimization
// combination must give the same masks, bit for bit, as the reference ray caster.

#include "TestScenes.h"

#include "bake/peers/ReferenceCaster.h"

#include <catch2/catch.hpp>

namespace penumbra::test {

/// Receivers on a subset of @p tris: @p perTriangle points on every @p stride-th triangle.
inline void addReceiversOnEvery(ReceiverSet& set, const std::vector<Triangle>& tris, size_t stride, int perTriangle, uint64_t seed) {
    std::vector<Triangle> some;
    for (size_t i = 0; i < tris.size(); i += stride) some.push_back(tris[i]);
    addReceiversOnTriangles(set, some, seed, perTriangle);
}

}  // namespace penumbra::test
