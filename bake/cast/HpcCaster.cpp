// `--method hpc`: hierarchical penumbra casting as the pipeline runs it. Receivers are cut into
// memory tiles (--memory-budget) cast one after another, each replaying the blockers; within a
// tile, threads cast disjoint sub-tiles (PenumbraCaster).

#include "bake/cast/Caster.h"
#include "bake/cast/PenumbraCaster.h"
#include "bake/cast/SampleMaskTable.h"
#include "stream/util/Memory.h"
#include "stream/util/Progress.h"
#include "stream/util/StopRequest.h"

#include <numeric>

namespace penumbra {
namespace {

/// Within a memory tile, threads work on disjoint sub-tiles, four per thread: more sub-tiles even
/// out uneven work (measured on GRIDS with a barrier per chunk, 2 threads: 2 per thread cast in
/// 4.28 s, 4 in 3.86 s, 8 in 3.92 s; docs/performance.md, "Parallelism").
int subTiles(int threads) { return threads > 1 ? 4 * threads : 1; }

class HpcCaster final : public Caster {
public:
    explicit HpcCaster(const CastContext& context) : c_(context) {}

    void cast(TriangleSource& blockers, uint32_t first, const CastSink& sink) override {
        std::vector<uint32_t> ids(c_.receivers.size() - first);
        std::iota(ids.begin(), ids.end(), first);
        const TileHooks* hooks = first == 0 ? c_.tileHooks : nullptr;
        if (hooks && hooks->select) ids = hooks->select(std::move(ids));
        const auto tiles = partitionReceivers(c_.receivers, ids, std::max(1, c_.memoryTiles));
        ProgressReporter progress("cast", blockers.sizeHint().value_or(0) * tiles.size(), c_.quiet);
        std::vector<Triangle> chunk(kTriangleChunk);
        for (size_t t = 0; t < tiles.size(); ++t) {
            if (hooks && hooks->restore && hooks->restore(t, tiles.size(), tiles[t])) continue;
            double readSeconds = 0;
            PenumbraCaster caster(c_.samples, c_.receivers, c_.sampleSets, c_.options, subTiles(c_.threads), tiles[t]);
            // The first tile of the bake reads the replay the bucket pass left ready.
            if (!fresh_) blockers.rewind();
            fresh_ = false;
            for (;;) {
                size_t n;
                {
                    ScopedTimer timer(readSeconds);
                    n = blockers.read(chunk);
                }
                if (n == 0) break;
                const std::span<const Triangle> part(chunk.data(), n);
                // A receiver kind's pass over the faces (smooth shading) runs on this thread while
                // the tiles cast earlier chunks on the others.
                if (c_.observeChunk && !observed_) c_.observeChunk(part);
                caster.cast(part);
                progress.update(n);
                testPoint("cast");
                throwIfStopRequested("cast");  // the finished tiles are checkpointed; this one is cast again
            }
            observed_ = true;
            caster.finish(sink.masks);
            if (hooks && hooks->finished) hooks->finished(t, tiles.size(), tiles[t]);
            // Tile hierarchies are built on worker threads, in their malloc arenas; hand the freed
            // memory back before the next tile, or arenas keep it and RSS creeps past the plan.
            returnFreedMemory();
            CastStats s = caster.stats();
            s.replayReadSeconds = readSeconds;
            addSequential(stats_, s);
        }
        if (c_.observeChunk && !observed_) observeAll(blockers);  // every tile was restored
        progress.done();
    }

    CastStats stats() const override { return stats_; }

private:
    /// The receiver kind's pass over the faces, when no tile was cast to carry it.
    void observeAll(TriangleSource& blockers) {
        if (!fresh_) blockers.rewind();
        fresh_ = false;
        std::vector<Triangle> chunk(kTriangleChunk);
        while (size_t n = blockers.read(chunk)) c_.observeChunk(std::span<const Triangle>(chunk.data(), n));
        observed_ = true;
    }

    const CastContext c_;
    CastStats stats_;
    bool fresh_ = true, observed_ = false;
};

const CasterRegistration kHpc{{"hpc",
                               {.summary = "hierarchical penumbra casting (Laine & Aila 2005): exact, out of core"},
                               [](const CastContext& c) { return std::make_unique<HpcCaster>(c); },
                               nullptr,
                               nullptr}};

}  // namespace
}  // namespace penumbra
