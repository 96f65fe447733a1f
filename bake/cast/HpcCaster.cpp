// `--method hpc`: hierarchical penumbra casting as the pipeline runs it. Receivers are cut into
// memory tiles (--memory-budget) cast one after another, each replaying the blockers; within a
// tile, threads cast disjoint sub-tiles (PenumbraCaster). A tile in progress can be checkpointed
// and resumed at a position in the replay (TileProgress, docs/distributed.md).

#include "bake/cast/Caster.h"
#include "bake/cast/ClosedExemptions.h"
#include "bake/cast/PenumbraCaster.h"
#include "bake/cast/SampleMaskTable.h"
#include "stream/util/Memory.h"
#include "stream/util/Progress.h"
#include "stream/util/StopRequest.h"

#include <algorithm>
#include <cstring>
#include <numeric>

namespace penumbra {
namespace {

/// Within a memory tile, threads work on disjoint sub-tiles, four per thread unless the plan has
/// no room for their fixed state (MemoryPlan::subTilesPerThread): more sub-tiles even out uneven
/// work (measured on GRIDS with a barrier per chunk, 2 threads: 2 per thread cast in 4.28 s, 4 in
/// 3.86 s, 8 in 3.92 s; docs/performance.md, "Parallelism"). The bits do not depend on it.
/// MemoryPlan.h's subTilesAtOnce() counts these, and the exempt receivers' caster.
int subTiles(int threads, int perThread) { return threads > 1 ? perThread * threads : 1; }

/// How far a tile's cast is in the replay: blockers read, and (when progress is saved) a hash of
/// their bytes, so that a resumed tile can check that it skips exactly the blockers it restored.
struct ReplayCursor {
    uint64_t position = 0, hash = 0xcbf29ce484222325ull;
    bool hashing = false;

    void add(std::span<const Triangle> part) {
        position += part.size();
        if (!hashing) return;
        // FNV-1a over 64-bit words: a Triangle is 40 bytes, five words, no padding.
        static_assert(sizeof(Triangle) % sizeof(uint64_t) == 0);
        const auto* bytes = reinterpret_cast<const unsigned char*>(part.data());
        for (size_t i = 0; i < part.size_bytes(); i += sizeof(uint64_t)) {
            uint64_t word;
            std::memcpy(&word, bytes + i, sizeof word);
            hash = (hash ^ word) * 0x100000001b3ull;
        }
    }
};

/// The row of receiver @p r among a tile's sorted @p ids.
size_t rowOf(std::span<const uint32_t> ids, uint32_t r) { return size_t(std::lower_bound(ids.begin(), ids.end(), r) - ids.begin()); }

/// A tile's casters. `main` casts every receiver of the tile with the options as given, so closed
/// casters may skip closed faces for any of them. `exempt` casts the closed faces alone, with
/// closed casters off, for the receivers whose bits those skips could lose (ClosedExemptions.h):
/// their masks are the OR of both, every face's bits, as the reference finds them.
class TileCasters {
public:
    TileCasters(const CastContext& c, std::span<const uint32_t> open, std::vector<uint32_t> exempt, int tiles)
        : c_(c), exemptIds_(std::move(exempt)) {
        if (open.empty()) return;
        main_.emplace(c.samples, c.receivers, c.sampleSets, c.options, tiles, open);
        if (exemptIds_.empty()) return;
        // Few receivers: one tile, and no sample tables to build for them.
        exemptOptions_ = c.options;
        exemptOptions_.closedCasters = exemptOptions_.sampleTable = false;
        exempt_.emplace(c.samples, c.receivers, c.sampleSets, exemptOptions_, 1, exemptIds_);
    }

    explicit operator bool() const { return main_.has_value(); }
    PenumbraCaster& main() { return *main_; }

    void cast(std::span<const Triangle> part) {
        main_->cast(part);
        if (!exempt_) return;
        closed_.clear();
        for (const Triangle& t : part)
            if (t.flags & kTriangleClosed) closed_.push_back(t);
        for (size_t at = 0; at < closed_.size(); at += kClosedExemptChunk)
            exempt_->cast(std::span<const Triangle>(closed_).subspan(at, std::min(kClosedExemptChunk, closed_.size() - at)));
    }

    /// Waits until both have cast every chunk.
    void flush() {
        main_->flush();
        if (exempt_) exempt_->flush();
    }

    /// Every receiver to @p visit once (PenumbraCaster::finish()), with @p visited counting them.
    void finish(const MaskVisitor& visit, const std::function<void(uint64_t)>& visited = {}) {
        if (!exempt_) return main_->finish(visit, visited);
        const int groups = c_.samples.groupCount();
        VisibilityMasks extra(exemptIds_.size(), groups);
        std::vector<uint8_t> extraFull(exemptIds_.size(), 0);
        exempt_->finish([&](uint32_t r, const uint64_t* words, bool full) {
            const size_t row = rowOf(exemptIds_, r);
            extraFull[row] = full;
            if (words) std::copy(words, words + groups, extra.row(row));
        });
        main_->finish([&](uint32_t r, const uint64_t* words, bool full) {
            if (full || !std::binary_search(exemptIds_.begin(), exemptIds_.end(), r)) return visit(r, words, full);
            const size_t row = rowOf(exemptIds_, r);
            if (extraFull[row]) return visit(r, nullptr, true);
            thread_local std::vector<uint64_t> merged;
            merged.assign(extra.row(row), extra.row(row) + groups);
            bool any = false, all = groups > 0;
            for (int k = 0; k < groups; ++k) {
                merged[k] |= words ? words[k] : 0;
                any = any || merged[k], all = all && merged[k] == c_.samples.groups[k].fullMask();
            }
            // Reported as one caster would: full umbra as such, nothing blocked as null.
            if (all) return visit(r, nullptr, true);
            visit(r, any ? merged.data() : nullptr, false);
        }, visited);
    }

    /// The two run at once: times are the main one's, work and memory add up.
    CastStats stats() const {
        CastStats s = main_->stats();
        if (!exempt_) return s;
        const CastStats e = exempt_->stats();
        s.hierarchyBuildSeconds += e.hierarchyBuildSeconds, s.hierarchyBuildWallSeconds += e.hierarchyBuildWallSeconds;
        s.rebuilds += e.rebuilds, s.hardShadowTests += e.hardShadowTests, s.tableDecidedRelations += e.tableDecidedRelations;
        s.peakLiveMasks += e.peakLiveMasks, s.peakMaskBytes += e.peakMaskBytes;
        s.peakHierarchyBytes += e.peakHierarchyBytes, s.receiverBytes += e.receiverBytes;
        return s;
    }

private:
    const CastContext& c_;
    std::vector<uint32_t> exemptIds_;  ///< sorted
    CastOptions exemptOptions_;
    std::optional<PenumbraCaster> main_, exempt_;
    std::vector<Triangle> closed_;  ///< the current chunk's closed faces, for `exempt`
};

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
        progress.setRuns(blockers.costRuns());
        for (size_t t = 0; t < tiles.size(); ++t) {
            if (hooks && hooks->restore) {
                progress.pause();  // a restored tile's receivers are shaded as a phase of their own
                const bool restored = hooks->restore(t, tiles.size(), tiles[t]);
                progress.resume();
                if (restored) {
                    progress.skip(blockers.sizeHint().value_or(0));  // a tile restored from a checkpoint is done
                    continue;
                }
            }
            castTile(blockers, Tile{t, tiles.size(), tiles[t]}, sink, hooks, progress);
            if (hooks && hooks->finished) hooks->finished(t, tiles.size(), tiles[t]);
            // Tile hierarchies are built on worker threads, in their malloc arenas; hand the freed
            // memory back before the next tile, or arenas keep it and RSS creeps past the plan.
            returnFreedMemory();
        }
        if (c_.observeChunk && !observed_) observeAll(blockers);  // every tile was restored
        progress.done();
    }

    CastStats stats() const override { return stats_; }

private:
    struct Tile {
        size_t index, count;
        std::span<const uint32_t> ids;  ///< sorted
    };

    /// Casts one memory tile against the whole replay, or against the rest of it after a
    /// checkpoint of its progress, and reports every one of its receivers to @p sink.
    void castTile(TriangleSource& blockers, const Tile& tile, const CastSink& sink, const TileHooks* hooks,
                  ProgressReporter& progress) {
        const bool saves = hooks && hooks->saveProgress;
        ReplayCursor cursor;
        cursor.hashing = saves;
        rewindOnce(blockers);
        std::optional<TileProgress> prior = saves ? hooks->resume(tile.index, tile.count, tile.ids) : std::nullopt;
        double exemptSeconds = 0;
        const std::vector<uint32_t> exempt = findExempt(blockers, tile.ids, exemptSeconds);
        if (prior && !skipTo(blockers, *prior, cursor)) {
            hooks->rejectProgress(tile.index, tile.count);
            prior.reset();
            blockers.rewind();
            cursor = ReplayCursor{0, ReplayCursor{}.hash, saves};
        }
        // Receivers in full umbra already are final: only the others are cast.
        std::vector<uint32_t> open, openExempt;
        for (size_t i = 0; i < tile.ids.size(); ++i)
            if (!prior || !fullRow(prior->masks.row(i))) {
                open.push_back(tile.ids[i]);
                if (std::binary_search(exempt.begin(), exempt.end(), tile.ids[i])) openExempt.push_back(tile.ids[i]);
            }
        TileCasters caster(c_, open, std::move(openExempt), subTiles(c_.threads, c_.subTilesPerThread));
        // Triangles are counted as the sub-tiles finish them, with the work they took, so the
        // share and ETA follow the work rather than the count (ProgressEstimate.h); what a resumed
        // tile skipped is done.
        if (caster) caster.main().setProgress([&progress](uint64_t triangles, uint64_t work) { progress.updateMeasured(triangles, work); });
        if (prior) progress.skip(prior->replayed);
        double readSeconds = 0;
        std::vector<Triangle> chunk(kTriangleChunk);
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
            observe(part, cursor.position);
            cursor.add(part);
            if (caster) caster.cast(part);
            progress.update(caster ? 0 : n);  // 0: where Ctrl-C (requestCancel) stops the cast
            const bool due = saves && hooks->progressDue();
            if (due) hooks->saveProgress(tile.index, tile.count, tile.ids, snapshot(caster, tile, prior, cursor));
            testPoint("cast");
            // A SIGTERM is the last chance to save the tile's progress (StopRequest.h).
            if (saves && !due && stopRequested())
                hooks->saveProgress(tile.index, tile.count, tile.ids, snapshot(caster, tile, prior, cursor));
            throwIfStopRequested("cast");  // the finished tiles and this one's progress are checkpointed
        }
        observed_ = true;
        if (caster) caster.flush();  // the last chunks are the cast's: they credit its line
        double shadeSeconds = 0;
        shade(caster, tile, prior, sink, progress, shadeSeconds);
        if (!caster) return;
        CastStats s = caster.stats();
        s.replayReadSeconds = readSeconds;
        s.shadeSeconds = shadeSeconds;
        s.closedExemptReceivers = exempt.size();
        s.closedExemptSeconds = exemptSeconds;
        addSequential(stats_, s);
    }

    /// The receivers of @p ids that closed casters must not skip for: a pass over the whole
    /// replay (every closed face, wherever a resumed tile starts), which is then rewound, timed
    /// into @p seconds. None when closed casters are off (also when no closed solid stayed closed).
    std::vector<uint32_t> findExempt(TriangleSource& blockers, std::span<const uint32_t> ids, double& seconds) {
        if (!c_.options.closedCasters || ids.empty()) return {};
        ScopedTimer timer(seconds);
        std::vector<uint32_t> exempt = findClosedExemptions(blockers, c_.samples, c_.receivers, c_.sampleSets, ids, c_.options);
        blockers.rewind();
        return exempt;
    }

    /// Reads the first @p prior.replayed blockers (observing them, casting none) and checks their
    /// hash. @return false when the replay is not what the progress was saved from.
    bool skipTo(TriangleSource& blockers, const TileProgress& prior, ReplayCursor& cursor) {
        std::vector<Triangle> chunk(kTriangleChunk);
        while (cursor.position < prior.replayed) {
            const size_t want = size_t(std::min<uint64_t>(chunk.size(), prior.replayed - cursor.position));
            const size_t n = blockers.read(std::span<Triangle>(chunk.data(), want));
            if (n == 0) return false;
            observe(std::span<const Triangle>(chunk.data(), n), cursor.position);
            cursor.add(std::span<const Triangle>(chunk.data(), n));
        }
        return cursor.hash == prior.replayHash;
    }

    /// The tile's masks now: what the caster found so far ORed into what @p prior restored.
    TileProgress snapshot(TileCasters& caster, const Tile& tile, const std::optional<TileProgress>& prior,
                          const ReplayCursor& cursor) const {
        TileProgress now{cursor.position, cursor.hash,
                         prior ? prior->masks : VisibilityMasks(tile.ids.size(), c_.samples.groupCount())};
        // finish() only flushes and reads the tiles, so the cast goes on after it.
        if (caster) caster.finish([&](uint32_t r, const uint64_t* words, bool full) {
            uint64_t* row = now.masks.row(rowOf(tile.ids, r));
            for (int k = 0; k < now.masks.groups; ++k)
                row[k] = full ? c_.samples.groups[k].fullMask() : row[k] | (words ? words[k] : 0);
        });
        return now;
    }

    /// The pass that hands the tile's receivers to @p sink, where they are shaded, as a phase of
    /// its own (`[shade]`, counting receivers) timed into @p seconds. Under a light of thousands
    /// of samples it can take longer than the cast, whose line would sit at 99.9 % through it
    /// without an ETA. The cast's line closes before the last tile's pass and is paused during
    /// the others'.
    void shade(TileCasters& caster, const Tile& tile, const std::optional<TileProgress>& prior, const CastSink& sink,
               ProgressReporter& castProgress, double& seconds) const {
        ScopedTimer timer(seconds);
        const bool last = tile.index + 1 == tile.count;
        if (last) castProgress.done();
        else castProgress.pause();
        ProgressReporter shading("shade", tile.ids.size(), c_.quiet);
        report(caster, tile, prior, sink, [&shading](uint64_t n) { shading.update(n); });
        shading.done();
        if (!last) castProgress.resume();
    }

    /// Every receiver of the tile to @p sink once: cast ones with @p prior ORed in, the ones
    /// @p prior had in full umbra as such. @p visited counts them as they go.
    void report(TileCasters& caster, const Tile& tile, const std::optional<TileProgress>& prior, const CastSink& sink,
                const std::function<void(uint64_t)>& visited) const {
        if (prior) {
            uint64_t full = 0;
            for (size_t i = 0; i < tile.ids.size(); ++i)
                if (fullRow(prior->masks.row(i))) sink.masks(tile.ids[i], nullptr, true), ++full;
            visited(full);
        }
        if (!caster) return;
        if (!prior) return caster.finish(sink.masks, visited);
        caster.finish([&](uint32_t r, const uint64_t* words, bool full) {
            if (full) return sink.masks(r, nullptr, true);
            thread_local std::vector<uint64_t> merged;
            const uint64_t* before = prior->masks.row(rowOf(tile.ids, r));
            merged.assign(before, before + prior->masks.groups);
            if (words)
                for (size_t k = 0; k < merged.size(); ++k) merged[k] |= words[k];
            sink.masks(r, merged.data(), false);  // shaded as a merge shades ORed shard masks
        }, visited);
    }

    bool fullRow(const uint64_t* row) const {
        for (int k = 0; k < c_.samples.groupCount(); ++k)
            if (row[k] != c_.samples.groups[k].fullMask()) return false;
        return c_.samples.groupCount() > 0;
    }

    /// The first tile of the bake reads the replay the bucket pass left ready; later ones rewind.
    void rewindOnce(TriangleSource& blockers) {
        if (!fresh_) blockers.rewind();
        fresh_ = false;
    }

    /// Hands @p part, at replay position @p at, to the kind's pass over the faces, once per
    /// blocker whatever the tiles and resumes (chunks fall the same way on every read).
    void observe(std::span<const Triangle> part, uint64_t at) {
        if (!c_.observeChunk || observed_ || at < observedUpTo_) return;
        c_.observeChunk(part);
        observedUpTo_ = at + part.size();
    }

    /// The receiver kind's pass over the faces, when no tile was cast to carry it.
    void observeAll(TriangleSource& blockers) {
        rewindOnce(blockers);
        std::vector<Triangle> chunk(kTriangleChunk);
        for (uint64_t at = 0; size_t n = blockers.read(chunk); at += n) observe(std::span<const Triangle>(chunk.data(), n), at);
        observed_ = true;
    }

    const CastContext c_;
    CastStats stats_;
    bool fresh_ = true, observed_ = false;
    uint64_t observedUpTo_ = 0;  ///< blockers the kind has seen, while observed_ is false
};

const CasterRegistration kHpc{{"hpc",
                               {.memoryTiles = true, .summary = "hierarchical penumbra casting (Laine & Aila 2005): exact, out of core"},
                               [](const CastContext& c) { return std::make_unique<HpcCaster>(c); },
                               nullptr,
                               nullptr}};

}  // namespace
}  // namespace penumbra
