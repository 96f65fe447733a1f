#include "stream/BlockCyclicSource.h"

#include <algorithm>

namespace penumbra {

uint64_t BlockShare::triangles(uint64_t total) const {
    const uint64_t round = block * count;  // one block of every share
    const uint64_t rest = total % round;
    const uint64_t inLast = std::min(block, rest > index * block ? rest - index * block : 0);
    return total / round * block + inLast;
}

uint64_t blockSizeForShares(uint64_t total, uint32_t shares) {
    const uint64_t perBlock = total / (uint64_t(std::max(shares, 1u)) * 64);
    return std::clamp<uint64_t>(perBlock, 64, 65536);
}

BlockCyclicSource::BlockCyclicSource(TriangleSourcePtr inner, BlockShare share)
    : inner_(std::move(inner)), share_(share) {
    share_.count = std::max(share_.count, 1u);
    share_.block = std::max<uint64_t>(share_.block, 1);
}

size_t BlockCyclicSource::read(std::span<Triangle> out) {
    if (out.empty() || ended_) return 0;
    if (leftInBlock_ == 0) {
        // The blocks of the shares before this one (on the first block), or of all the others.
        const uint64_t gap = share_.block * (started_ ? share_.count - 1 : share_.index);
        started_ = true;
        if (inner_->skip(gap) < gap) return ended_ = true, 0;
        leftInBlock_ = share_.block;
    }
    const size_t n = inner_->read(out.first(size_t(std::min<uint64_t>(out.size(), leftInBlock_))));
    if (n == 0) ended_ = true;
    leftInBlock_ -= n;
    return n;
}

void BlockCyclicSource::rewind() {
    inner_->rewind();
    leftInBlock_ = 0, started_ = false, ended_ = false;
}

std::optional<uint64_t> BlockCyclicSource::sizeHint() const {
    const std::optional<uint64_t> all = inner_->sizeHint();
    if (!all) return std::nullopt;
    return share_.triangles(*all);
}

std::optional<uint64_t> BlockCyclicSource::knownSize() const {
    const std::optional<uint64_t> all = inner_->knownSize();
    if (!all) return std::nullopt;
    return share_.triangles(*all);
}

}  // namespace penumbra
