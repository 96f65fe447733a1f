#include "procedural/IndexedSource.h"

#include <tbb/parallel_for.h>

#include <algorithm>

namespace penumbra {

size_t IndexedSource::read(std::span<Triangle> out) {
    size_t n = size_t(std::min<uint64_t>(out.size(), count_ - next_));
    const uint64_t base = next_;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) triangle(base + i, out[i]);
    });
    next_ += n;
    return n;
}

}  // namespace penumbra
