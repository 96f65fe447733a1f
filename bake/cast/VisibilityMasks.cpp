#include "bake/cast/VisibilityMasks.h"

#include <bit>

namespace penumbra {

VisibilityMasks::VisibilityMasks(size_t receivers, int groupCount, std::span<const uint32_t> kept)
    : groups(groupCount), words(kept.size() * size_t(groupCount), 0), rowOf(receivers, kNotKept) {
    for (size_t i = 0; i < kept.size(); ++i) rowOf[kept[i]] = uint32_t(i);
}

bool VisibilityMasks::blocked(size_t r, const LightSamples& s, uint32_t sample) const {
    for (int k = 0; k < groups; ++k) {
        const LightSampleGroup& g = s.groups[k];
        if (sample >= g.first && sample < g.first + g.count) return (row(r)[k] >> (sample - g.first)) & 1u;
    }
    return false;
}

double VisibilityMasks::visibleFraction(size_t r, const LightSamples& s) const {
    uint64_t blockedSamples = 0;
    for (int k = 0; k < groups; ++k) blockedSamples += std::popcount(row(r)[k]);
    return s.sampleCount ? 1.0 - double(blockedSamples) / s.sampleCount : 1.0;
}

std::vector<uint64_t> VisibilityMasks::toDumpLayout(const LightSamples& s) const {
    const size_t n = receivers(), words = (size_t(s.sampleCount) + 63) / 64;
    std::vector<uint64_t> out(n * words, 0);
    for (size_t r = 0; r < n; ++r)
        for (int k = 0; k < groups && keeps(r); ++k) {
            const LightSampleGroup& g = s.groups[k];
            for (uint64_t bits = row(r)[k]; bits; bits &= bits - 1) {
                uint32_t sample = g.first + uint32_t(std::countr_zero(bits));
                out[r * words + sample / 64] |= 1ull << (sample % 64);
            }
        }
    return out;
}

uint64_t VisibilityMasks::blockedCount() const {
    uint64_t n = 0;
    for (uint64_t w : words) n += std::popcount(w);
    return n;
}

}  // namespace penumbra
