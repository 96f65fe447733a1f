#pragma once
// Exactness for generated scenes: hierarchical penumbra casting with every optimization
// combination must give the same masks, bit for bit, as the reference ray caster.

#include "TestScenes.h"

#include "bake/ReferenceCaster.h"

#include <catch2/catch.hpp>

namespace penumbra::test {

/// Receivers on a subset of @p tris: @p perTriangle points on every @p stride-th triangle.
inline void addReceiversOnEvery(ReceiverSet& set, const std::vector<Triangle>& tris, size_t stride, int perTriangle, uint64_t seed) {
    std::vector<Triangle> some;
    for (size_t i = 0; i < tris.size(); i += stride) some.push_back(tris[i]);
    addReceiversOnTriangles(set, some, seed, perTriangle);
}

inline void requireExactBake(const std::string& scene, const LightDesc& light, const ReceiverSet& receivers,
                             const std::vector<Triangle>& triangles) {
    LightSamples samples = generateLightSamples({light}, 64, 7);
    std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    VisibilityMasks reference = castReference(samples, receivers, sets, triangles, CastOptions().epsilon);
    INFO(scene << ": " << reference.blockedCount() << " blocked of " << receivers.size() * samples.sampleCount);
    REQUIRE(reference.blockedCount() > 0);
    REQUIRE(reference.blockedCount() < uint64_t(receivers.size()) * samples.sampleCount);
    for (const auto& [name, options] : optionVariants()) {
        for (int tiles : {1, 3}) {
            INFO(name << ", tiles " << tiles);
            VisibilityMasks hpc = castHpc(samples, receivers, sets, triangles, options, tiles);
            CHECK(hpc.blockedCount() == reference.blockedCount());
            CHECK(hpc.words == reference.words);
        }
    }
}

}  // namespace penumbra::test
