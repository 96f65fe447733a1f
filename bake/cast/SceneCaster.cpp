#include "bake/cast/SceneCaster.h"

#include "stream/util/Progress.h"

#include <algorithm>

namespace penumbra {

ReceiverSet receiversFrom(const ReceiverSet& set, size_t first) {
    if (first == 0) return set;
    ReceiverSet out;
    out.position.assign(set.position.begin() + first, set.position.end());
    out.normal.assign(set.normal.begin() + first, set.normal.end());
    return out;
}

void SceneCaster::cast(TriangleSource& blockers, uint32_t first, const CastSink& sink) {
    Stopwatch watch;
    if (!read_) {
        blockers.rewind();
        all_ = readAll(blockers);
        read_ = true;
        if (c_.observeChunk)
            for (size_t i = 0; i < all_.size(); i += kTriangleChunk)
                c_.observeChunk(std::span<const Triangle>(all_).subspan(i, std::min(kTriangleChunk, all_.size() - i)));
        all_.resize(dropNonCasting(all_));  // seen by the kind's pass, never a blocker
    }
    const ReceiverSet targets = receiversFrom(c_.receivers, first);
    ProgressReporter progress(phase_, targets.size(), c_.quiet);
    const VisibilityMasks masks =
        castAll_(targets, std::span<const uint32_t>(c_.sampleSets).subspan(first), all_, [&](uint64_t n) { progress.update(n); });
    progress.done();
    // The cast's time stops before the report (shading), as hpc's does. Shading was serial here
    // and cost about a microsecond per receiver, more with translucent blockers' depths.
    stats_.castSeconds += watch.seconds();
    stats_.trianglesProcessed += all_.size();
    reportInParallel(first, first + uint32_t(targets.size()), [&](uint32_t r) {
        const uint32_t i = r - first;
        if (sink.masksWithDepth && i < depths_.size()) sink.masksWithDepth(r, masks.row(i), false, depths_[i].get());
        else sink.masks(r, masks.row(i), false);
    });
    depths_.clear();
}

}  // namespace penumbra
