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

    explicit MaskPool(int words) : words_(words), blockShift_(blockShiftFor(words)) {}
    int words() const { return words_; }

    /// A zeroed mask; reuses released slots first.
    uint32_t allocate();
    void release(uint32_t slot);
    uint64_t* data(uint32_t slot) { return blocks_[slot >> blockShift_].get() + size_t(slot & blockMask()) * words_; }
    const uint64_t* data(uint32_t slot) const { return blocks_[slot >> blockShift_].get() + size_t(slot & blockMask()) * words_; }

    size_t live() const { return live_; }
    size_t peakLive() const { return peakLive_; }
    /// Bytes of mask storage the pool holds (its high-water mark: blocks are never returned).
    size_t bytes() const { return blocks_.size() * (size_t(1) << blockShift_) * words_ * sizeof(uint64_t); }
    /// Most bytes a pool's blocks hold beyond its live masks: one block, at most kBlockBytes (or a
    /// single mask, when one is larger), for memory planning.
    static size_t slackBytes(int words) { return (size_t(1) << blockShiftFor(words)) * size_t(words) * sizeof(uint64_t); }

private:
    /// Masks come in blocks of at most this many bytes (4096 masks of up to four words, fewer of
    /// more): a fixed 4096 masks of 16,384 words (16 lights of 65,536 samples) were 512 MiB, the
    /// first time one receiver needed a mask.
    static constexpr size_t kBlockBytes = 128 << 10;
    static int blockShiftFor(int words) {
        int shift = 12;  // 4096 masks
        while (shift > 0 && (size_t(1) << shift) * size_t(words) * sizeof(uint64_t) > kBlockBytes) --shift;
        return shift;
    }
    uint32_t blockMask() const { return (1u << blockShift_) - 1u; }
    int words_;
    int blockShift_;
    std::vector<std::unique_ptr<uint64_t[]>> blocks_;
    std::vector<uint32_t> free_;
    uint32_t next_ = 0;
    size_t live_ = 0, peakLive_ = 0;
};

}  // namespace penumbra
