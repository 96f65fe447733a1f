#pragma once
/// @file MaskPool.h
/// @brief On-demand receiver bit masks (optimization D): fixed-size masks handed out from a pool
/// and returned when a receiver reaches full umbra.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace penumbra {

/// @brief A pool of zero-initialised masks of `words` uint64 each. Slots are stable: growing the
/// pool never moves existing masks, so pointers stay valid until release().
class MaskPool {
public:
    static constexpr uint32_t kNone = ~0u;

    explicit MaskPool(int words) : words_(words) {}
    int words() const { return words_; }

    /// A zeroed mask; reuses released slots first.
    uint32_t allocate();
    void release(uint32_t slot);
    uint64_t* data(uint32_t slot) { return blocks_[slot / kBlock].get() + size_t(slot % kBlock) * words_; }
    const uint64_t* data(uint32_t slot) const { return blocks_[slot / kBlock].get() + size_t(slot % kBlock) * words_; }

    size_t live() const { return live_; }
    size_t peakLive() const { return peakLive_; }
    /// Bytes of mask storage the pool holds (its high-water mark: blocks are never returned).
    size_t bytes() const { return blocks_.size() * kBlock * words_ * sizeof(uint64_t); }

private:
    static constexpr uint32_t kBlock = 4096;  // masks per block
    int words_;
    std::vector<std::unique_ptr<uint64_t[]>> blocks_;
    std::vector<uint32_t> free_;
    uint32_t next_ = 0;
    size_t live_ = 0, peakLive_ = 0;
};

}  // namespace penumbra
