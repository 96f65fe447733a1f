#include "bake/cast/MaskPool.h"

#include <algorithm>

namespace penumbra {

uint32_t MaskPool::allocate() {
    uint32_t slot;
    if (!free_.empty()) {
        slot = free_.back();
        free_.pop_back();
    } else {
        slot = next_++;
        if (slot / kBlock >= blocks_.size())
            blocks_.push_back(std::make_unique<uint64_t[]>(size_t(kBlock) * words_));  // value-initialised: zero
    }
    std::fill_n(data(slot), words_, 0ull);
    peakLive_ = std::max(peakLive_, ++live_);
    return slot;
}

void MaskPool::release(uint32_t slot) {
    free_.push_back(slot);
    --live_;
}

}  // namespace penumbra
