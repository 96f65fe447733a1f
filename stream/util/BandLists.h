#pragma once
/// @file BandLists.h
/// @brief Items of a chunk listed per band of image rows, each band's in item order: a counting
/// sort, so that bands drawn in parallel each read their own list and still see the items in
/// stream order (both rasterizers: the camera's z-buffer and the light's view).

#include <cstddef>
#include <cstdint>
#include <vector>

namespace penumbra {

struct BandLists {
    std::vector<uint32_t> first;    ///< band b's items are members[first[b] .. first[b + 1])
    std::vector<uint32_t> members;  ///< item indices, band after band
    std::vector<uint32_t> cursor;   ///< scratch of build()

    /// @brief Lists @p count items in @p bands bands; @p range(i, lo, hi) sets item i's bands
    /// [lo, hi] (lo > hi: none). The buffers are kept for the next call.
    template <class Range>
    void build(int bands, size_t count, Range range) {
        first.assign(size_t(bands) + 1, 0);
        int lo = 0, hi = -1;
        for (size_t i = 0; i < count; ++i) {
            range(i, lo, hi);
            for (int b = lo; b <= hi; ++b) ++first[size_t(b) + 1];
        }
        for (int b = 0; b < bands; ++b) first[size_t(b) + 1] += first[size_t(b)];
        members.resize(first[size_t(bands)]);
        cursor.assign(first.begin(), first.end() - 1);
        for (size_t i = 0; i < count; ++i) {
            range(i, lo, hi);
            for (int b = lo; b <= hi; ++b) members[cursor[size_t(b)]++] = uint32_t(i);
        }
    }
};

}  // namespace penumbra
