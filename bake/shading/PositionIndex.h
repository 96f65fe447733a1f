#pragma once
/// @file PositionIndex.h
/// @brief A flat hash table from a vertex position's exact float bits to a 32-bit value, for
/// smooth shading's per-vertex table (VertexBend).
///
/// Why not std::unordered_map: VertexBend::add() probes the table for every vertex of every face
/// that passes its Bloom filter, millions per bake, and a node map's probe follows a bucket
/// pointer to a node in another cache line (two to three misses). Here key and value sit side by
/// side in one array, probed linearly, so a hit costs one miss. Entries are never erased.

#include <cstddef>
#include <cstdint>
#include <vector>

namespace penumbra {

/// @brief A vertex position as the bits of its three floats (+0 and -0 made equal by the caller).
struct PositionKey {
    uint32_t x, y, z;
    bool operator==(const PositionKey&) const = default;
    /// A mix of the three words; the low bits index the table and the Bloom filter.
    size_t hash() const {
        const uint64_t h = (uint64_t(x) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(y) * 0xC2B2AE3D27D4EB4Full) ^ (uint64_t(z) * 0x165667B19E3779F9ull);
        return size_t(h ^ (h >> 29));
    }
};

/// @brief Open addressing with linear probing; at most three quarters full, doubled when it
/// would be fuller. The value kEmpty marks a free entry, so it is not a storable value.
class PositionIndex {
public:
    static constexpr uint32_t kEmpty = ~0u;
    struct Entry {
        PositionKey key;
        uint32_t value = kEmpty;
    };

    /// The value of @p key, or kEmpty.
    uint32_t find(const PositionKey& key) const {
        if (entries_.empty()) return kEmpty;
        for (size_t i = key.hash() & mask_;; i = (i + 1) & mask_) {
            const Entry& e = entries_[i];
            if (e.value == kEmpty || e.key == key) return e.value;
        }
    }
    /// The value of @p key, inserted as kEmpty if new: the caller stores a value other than
    /// kEmpty in it before the next call.
    uint32_t& findOrInsert(const PositionKey& key) {
        if (4 * (size_ + 1) > 3 * entries_.size()) grow();
        for (size_t i = key.hash() & mask_;; i = (i + 1) & mask_) {
            Entry& e = entries_[i];
            if (e.value == kEmpty) {
                e.key = key, ++size_;
                return e.value;
            }
            if (e.key == key) return e.value;
        }
    }
    size_t size() const { return size_; }
    /// Every entry, free ones included (value kEmpty): for a pass over the keys.
    const std::vector<Entry>& entries() const { return entries_; }
    uint64_t bytes() const { return entries_.capacity() * sizeof(Entry); }
    /// The most bytes the table takes per key, at the moment of growth, when the old array (at
    /// three quarters) and the new one are both alive: 16 / 0.75 + 32 / 0.75.
    static constexpr uint64_t kPeakBytesPerKey = 64;

private:
    void grow() {
        std::vector<Entry> old = std::move(entries_);
        entries_.assign(old.empty() ? 64 : 2 * old.size(), Entry{});
        mask_ = entries_.size() - 1;
        for (const Entry& e : old) {
            if (e.value == kEmpty) continue;
            size_t i = e.key.hash() & mask_;
            while (entries_[i].value != kEmpty) i = (i + 1) & mask_;
            entries_[i] = e;
        }
    }
    std::vector<Entry> entries_;
    size_t mask_ = 0, size_ = 0;
};

}  // namespace penumbra
