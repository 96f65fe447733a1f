#include "bake/methods/StreamedCaster.h"

#include <vector>

namespace penumbra {

void StreamedCaster::observeOnce(TriangleSource& blockers) {
    if (observed_ || !c_.observeChunk) return;
    observed_ = true;
    blockers.rewind();
    std::vector<Triangle> chunk(kTriangleChunk);
    while (size_t n = blockers.read(chunk)) c_.observeChunk(std::span<const Triangle>(chunk.data(), n));
}

std::function<void(std::span<const Triangle>)> StreamedCaster::takeObserver() {
    if (observed_ || !c_.observeChunk) return {};
    observed_ = true;
    return c_.observeChunk;
}

}  // namespace penumbra
