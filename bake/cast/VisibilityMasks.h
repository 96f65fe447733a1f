#pragma once
/// @file VisibilityMasks.h
/// @brief The result of a cast for every receiver: one 64-bit word per light-sample group.

#include "bake/light/Light.h"

#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

/// @brief Blocked relations of N receivers. Word k of receiver r holds the samples of group k:
/// bit j set means sample groups[k].first + j is blocked. This layout makes group-umbra tests a
/// single compare; toDumpLayout() converts to the dense per-sample layout of masks.npy.
struct VisibilityMasks {
    int groups = 0;
    std::vector<uint64_t> words;  ///< N x groups

    VisibilityMasks() = default;
    VisibilityMasks(size_t receivers, int groupCount) : groups(groupCount), words(receivers * groupCount, 0) {}
    size_t receivers() const { return groups ? words.size() / groups : 0; }
    uint64_t* row(size_t r) { return words.data() + r * groups; }
    const uint64_t* row(size_t r) const { return words.data() + r * groups; }

    bool blocked(size_t r, const LightSamples& s, uint32_t sample) const;
    /// Visible fraction of the light (all lights together): unblocked samples / K.
    double visibleFraction(size_t r, const LightSamples& s) const;
    /// Dense layout: N x ceil(K/64) words, bit k%64 of word k/64 set when sample k is blocked.
    std::vector<uint64_t> toDumpLayout(const LightSamples& s) const;
    /// Number of blocked relations.
    uint64_t blockedCount() const;
};

}  // namespace penumbra
