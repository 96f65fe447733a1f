#pragma once
/// @file VisibilityMasks.h
/// @brief The result of a cast for every receiver: one 64-bit word per light-sample group.

#include "bake/light/Light.h"

#include <cassert>
#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

/// @brief Blocked relations of N receivers. Word k of receiver r holds the samples of group k:
/// bit j set means sample groups[k].first + j is blocked. This layout makes group-umbra tests a
/// single compare; toDumpLayout() converts to the dense per-sample layout of masks.npy.
///
/// A by-receivers shard casts a share of the receivers and keeps rows for those only (@p kept):
/// its masks then shrink with the shard count (MemoryDemand::castReceivers), at 4 bytes per
/// receiver for the row index. Only kept receivers may be asked for their row.
struct VisibilityMasks {
    static constexpr uint32_t kNotKept = ~0u;
    int groups = 0;
    std::vector<uint64_t> words;   ///< rows x groups
    std::vector<uint32_t> rowOf;   ///< per receiver: its row, or kNotKept; empty: row r is receiver r

    VisibilityMasks() = default;
    VisibilityMasks(size_t receivers, int groupCount) : groups(groupCount), words(receivers * groupCount, 0) {}
    /// @brief Rows for the receivers @p kept (distinct, each below @p receivers) only.
    VisibilityMasks(size_t receivers, int groupCount, std::span<const uint32_t> kept);
    size_t receivers() const { return !rowOf.empty() ? rowOf.size() : groups ? words.size() / groups : 0; }
    /// Whether receiver @p r has a row (every receiver, unless only a share is kept).
    bool keeps(size_t r) const { return rowOf.empty() || rowOf[r] != kNotKept; }
    uint64_t* row(size_t r) { return words.data() + rowIndex(r) * groups; }
    const uint64_t* row(size_t r) const { return words.data() + rowIndex(r) * groups; }

    bool blocked(size_t r, const LightSamples& s, uint32_t sample) const;
    /// Visible fraction of the light (all lights together): unblocked samples / K.
    double visibleFraction(size_t r, const LightSamples& s) const;
    /// Dense layout: N x ceil(K/64) words, bit k%64 of word k/64 set when sample k is blocked.
    std::vector<uint64_t> toDumpLayout(const LightSamples& s) const;
    /// Number of blocked relations.
    uint64_t blockedCount() const;

private:
    size_t rowIndex(size_t r) const {
        assert(keeps(r));
        return rowOf.empty() ? r : rowOf[r];
    }
};

}  // namespace penumbra
