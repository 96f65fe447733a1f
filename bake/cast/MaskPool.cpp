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
        // Not zeroed here: each mask is as it is handed out, so pages no mask reached stay untouched.
        if ((slot >> blockShift_) >= blocks_.size())
            blocks_.push_back(std::unique_ptr<uint64_t[]>(new uint64_t[(size_t(1) << blockShift_) * size_t(words_)]));
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
