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

void StreamedCaster::report(const Stopwatch& cast, uint32_t first, uint32_t end, const std::function<void(uint32_t)>& each) {
    castStats_.castSeconds += cast.seconds();
    reportInParallel(first, end, each);
}

}  // namespace penumbra
