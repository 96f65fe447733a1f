#include "procedural/IndexedSource.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cassert>

namespace penumbra {

size_t IndexedSource::read(std::span<Triangle> out) {
    size_t n = size_t(std::min<uint64_t>(out.size(), count_ - next_));
    const uint64_t base = next_;
    // Each range is written by exactly one task and only depends on its indices, so the bytes
    // do not depend on how TBB splits the work.
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
        fill(base + r.begin(), out.subspan(r.begin(), r.size()));
    });
    next_ += n;
    return n;
}

void IndexedSource::fill(uint64_t first, std::span<Triangle> out) const {
    for (size_t i = 0; i < out.size(); ++i) triangle(first + i, out[i]);
}

ItemSource::ItemSource(std::string name, uint64_t items, uint32_t perItem)
    : IndexedSource(std::move(name), items * perItem), perItem_(perItem) {
    assert(perItem >= 1 && perItem <= kMaxPerItem);
}

void ItemSource::triangle(uint64_t index, Triangle& out) const { fill(index, std::span<Triangle>(&out, 1)); }

void ItemSource::fill(uint64_t first, std::span<Triangle> out) const {
    std::array<Triangle, kMaxPerItem> scratch;
    size_t done = 0;
    while (done < out.size()) {
        const uint64_t index = first + done;
        const uint64_t k = index / perItem_;
        const uint32_t offset = uint32_t(index % perItem_);
        const size_t take = std::min<size_t>(perItem_ - offset, out.size() - done);
        if (offset == 0 && take == perItem_) {
            item(k, &out[done]);  // a whole item: build it in place
        } else {
            item(k, scratch.data());
            std::copy_n(scratch.begin() + offset, take, out.begin() + ptrdiff_t(done));
        }
        done += take;
    }
}

}  // namespace penumbra
