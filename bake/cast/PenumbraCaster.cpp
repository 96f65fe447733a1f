#include "bake/cast/PenumbraCaster.h"

#include "stream/util/Timer.h"

#include "bake/cast/BlockerBatch.h"
#include "bake/cast/SampleMaskTable.h"
#include "bake/cast/TileCaster.h"
#include "stream/TriangleSource.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <numeric>
#include <thread>

namespace penumbra {
namespace {

/// Blockers between two reports of a tile's work within a chunk (two relaxed atomic adds each).
constexpr size_t kWorkReportEvery = 256;
/// partitionReceivers() splits ranges at least this large on two threads at once.
constexpr size_t kParallelPartitionReceivers = 1 << 16;

}  // namespace

/// The tiles and the ring of prepared chunks. Tiles need not wait for one another: each casts the
/// chunks in order at its own pace, in a task of its own, and may run up to the ring's length
/// behind the others (a barrier per chunk left a thread idle at the end of every chunk). A tile
/// is held through an atomic busy flag; the holder re-checks after letting go, so no chunk is
/// missed.
struct PenumbraCaster::Impl {
    const LightSamples& samples;
    CastOptions options;
    std::vector<SampleMaskTable> tables;  ///< per light when options.sampleTable; shared by tiles
    std::vector<std::unique_ptr<TileCaster>> tiles;
    std::unique_ptr<BlockerCulls> culls;
    CastStats stats;
    std::vector<std::unique_ptr<BlockerBatch>> ring;
    std::atomic<uint64_t> published{0};  ///< chunks prepared and handed to the tiles
    /// Per tile: the next chunk it casts. Only the holder of the tile's busy flag touches it.
    std::vector<uint64_t> tileNext;
    std::unique_ptr<std::atomic<bool>[]> tileBusy;
    std::atomic<bool> failed{false};  ///< a tile threw; flush() rethrows it
    std::atomic<uint64_t> culledAtRoot{0};
    CastProgress progress;  ///< empty: nobody is watching
    tbb::task_group group;
    bool started = false;
    Stopwatch castWatch;

    Impl(const LightSamples& s, const CastOptions& o) : samples(s), options(o) {}
    void buildTiles(const ReceiverSet& receivers, std::span<const uint32_t> sampleSetOf,
                    std::span<const uint32_t> receiverIds, int tileCount);
    /// Casts every published chunk that tile @p t has not cast yet (at most @p most of them),
    /// unless another thread holds the tile (that thread then sees the new chunks before it lets
    /// go). A caller that stops early leaves the rest to the tasks of the next publish.
    void drain(size_t t, uint64_t most = UINT64_MAX);
    /// The tile's part of a chunk; the last tile to finish it counts the chunk's root culls.
    void castOnTile(size_t t, BlockerBatch& batch);
};

std::vector<std::vector<uint32_t>> partitionReceivers(const ReceiverSet& receivers, std::span<const uint32_t> ids,
                                                      int count) {
    std::vector<uint32_t> order(ids.begin(), ids.end());
    // Part p of the recursion lands in slot p; a range too small to split fills its first slot
    // and leaves the rest unset, so the parts, in slot order, do not depend on which thread made
    // them. The two halves of a split run side by side: at 2560x1920 the serial recursion (its
    // nth_element and each part's sort) was a fifth of the tiles' build wall time on two threads.
    const int pieces = std::max(1, count);
    std::vector<std::vector<uint32_t>> slots(static_cast<size_t>(pieces));
    std::vector<uint8_t> made(static_cast<size_t>(pieces), 0);
    auto split = [&](auto&& self, size_t begin, size_t end, int parts, int slot) -> void {
        if (parts <= 1 || end - begin <= 1) {
            slots[size_t(slot)].assign(order.begin() + begin, order.begin() + end);
            std::sort(slots[size_t(slot)].begin(), slots[size_t(slot)].end());
            made[size_t(slot)] = 1;
            return;
        }
        glm::vec3 lo(INFINITY), hi(-INFINITY);
        for (size_t i = begin; i < end; ++i)
            lo = glm::min(lo, receivers.position[order[i]]), hi = glm::max(hi, receivers.position[order[i]]);
        glm::vec3 e = hi - lo;
        int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
        int left = parts / 2;
        size_t mid = begin + (end - begin) * left / parts;
        std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end, [&](uint32_t a, uint32_t b) {
            float pa = receivers.position[a][axis], pb = receivers.position[b][axis];
            return pa < pb || (pa == pb && a < b);
        });
        auto leftHalf = [&] { self(self, begin, mid, left, slot); };
        auto rightHalf = [&] { self(self, mid, end, parts - left, slot + left); };
        if (end - begin < kParallelPartitionReceivers) leftHalf(), rightHalf();
        else tbb::parallel_invoke(leftHalf, rightHalf);
    };
    split(split, 0, order.size(), pieces, 0);
    std::vector<std::vector<uint32_t>> parts;
    for (size_t p = 0; p < slots.size(); ++p)
        if (made[p]) parts.push_back(std::move(slots[p]));
    return parts;
}

void PenumbraCaster::Impl::buildTiles(const ReceiverSet& receivers, std::span<const uint32_t> sampleSetOf,
                                      std::span<const uint32_t> receiverIds, int tileCount) {
    const auto parts = partitionReceivers(receivers, receiverIds, std::max(1, tileCount));
    tiles.resize(parts.size());
    const ReceiverEpsilon epsilon = receiverEpsilonOf(options);
    tbb::parallel_for(size_t(0), parts.size(), [&](size_t t) {
        tiles[t] = std::make_unique<TileCaster>(samples, options, options.sampleTable ? &tables : nullptr);
        std::vector<ReceiverInput> inputs;
        inputs.reserve(parts[t].size());
        for (uint32_t id : parts[t]) {
            glm::dvec3 p(receivers.position[id]);
            inputs.push_back({p, epsilon.at(p), id, sampleSetOf[id]});
        }
        tiles[t]->build(std::move(inputs));
    });
}

PenumbraCaster::PenumbraCaster(const LightSamples& samples, const ReceiverSet& receivers,
                               std::span<const uint32_t> sampleSetOf, const CastOptions& options, int tiles,
                               std::span<const uint32_t> receiverIds)
    : impl_(std::make_unique<Impl>(samples, options)) {
    Impl& m = *impl_;
    std::vector<uint32_t> all;
    if (receiverIds.empty()) {
        all.resize(receivers.size());
        std::iota(all.begin(), all.end(), 0u);
        receiverIds = all;
    }
    if (m.options.sampleTable)
        for (uint32_t l = 0; l < uint32_t(samples.lightCount()); ++l)
            m.tables.emplace_back(samples, l, m.options.sampleTableAngles, m.options.sampleTableOffsets, m.options.simd);
    {
        ScopedTimer timer(m.stats.hierarchyBuildWallSeconds);
        m.buildTiles(receivers, sampleSetOf, receiverIds, tiles);
    }
    // Rebuilds only drop receivers, so boxes from the first build stay conservative.
    Box receiversBox{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
    for (const auto& tile : m.tiles)
        if (!tile->hierarchy().nodes.empty()) {
            receiversBox.lo = glm::min(receiversBox.lo, tile->hierarchy().nodes[0].lo);
            receiversBox.hi = glm::max(receiversBox.hi, tile->hierarchy().nodes[0].hi);
        }
    m.culls = std::make_unique<BlockerCulls>(samples, m.options, receiversBox);
    // With several tiles, one can fall ringChunks() - 1 chunks behind the fastest before the
    // caller stops preparing and helps.
    m.ring.resize(ringChunks(m.tiles.size()));
    for (auto& b : m.ring) b = std::make_unique<BlockerBatch>();
    m.tileNext.assign(m.tiles.size(), 0);
    m.tileBusy = std::make_unique<std::atomic<bool>[]>(m.tiles.size());
    for (size_t t = 0; t < m.tiles.size(); ++t) m.tileBusy[t] = false;
}

PenumbraCaster::~PenumbraCaster() {
    // Only after an exception can tasks still be pending; they must not outlive the tiles.
    impl_->group.cancel();
    try {
        impl_->group.wait();
    } catch (...) {
    }
}

void PenumbraCaster::Impl::castOnTile(size_t t, BlockerBatch& batch) {
    const size_t n = batch.n, lights = size_t(samples.lightCount());
    TileCaster& tile = *tiles[t];
    uint8_t* reached = &batch.reached[t * n];
    uint64_t reported = tile.work(), credited = 0;
    const uint64_t count = tiles.size();
    for (size_t i = 0; i < n; ++i) {
        reached[i] = 0;
        // Work and triangles are reported as they are spent, not only when the chunk is through: a
        // heavy chunk (the cut-outs, replayed last) would otherwise hold the display's ETA near
        // zero while it drains, and its first finished share would arrive with every tile's work.
        // A tile credits one triangle per `count` it has cast; its share's rest comes at the end.
        if (progress && i % kWorkReportEvery == kWorkReportEvery - 1) {
            const uint64_t w = tile.work(), items = i / count - credited;
            progress(items, w - reported);
            reported = w, credited += items;
        }
        if (!batch.prepared[i].valid) continue;
        reached[i] = tile.castTriangle(batch.prepared[i], &batch.lightVolumes[i * lights], &batch.lightActive[i * lights]);
    }
    const uint64_t work = tile.work() - reported;
    // Each tile finishing the chunk completes its share of the chunk's triangles (tiles hold
    // near-equal receiver counts); the shares add up to n exactly. Counted as tiles cast, not
    // when the chunk is handed out, so the display reaches 100 % when the cast does.
    const int before = batch.remaining.fetch_sub(1);
    const uint64_t finished = count - size_t(before);
    // The share is at least floor(n / count), which is at least what was credited on the way.
    if (progress) progress(n * (finished + 1) / count - n * finished / count - credited, work);
    if (before != 1) return;
    if (options.countDelayForTestsUs > 0) std::this_thread::sleep_for(std::chrono::microseconds(options.countDelayForTestsUs));
    uint64_t culled = 0;  // the last tile: every tile's flags are written
    for (size_t i = 0; i < n; ++i) {
        bool any = false;
        for (size_t u = 0; u < tiles.size() && !any; ++u) any = batch.reached[u * n + i];
        culled += !any;
    }
    culledAtRoot += culled;
    batch.inUse.store(false);
}

void PenumbraCaster::Impl::drain(size_t t, uint64_t most) {
    for (;;) {
        if (tileBusy[t].exchange(true)) return;
        try {
            for (; tileNext[t] < published.load(); ++tileNext[t]) {
                if (most == 0) {
                    tileBusy[t].store(false);
                    return;
                }
                castOnTile(t, *ring[tileNext[t] % ring.size()]);
                --most;
            }
        } catch (...) {
            failed = true;  // the tile stays held: its state is unknown, nobody casts it again
            throw;
        }
        const uint64_t next = tileNext[t];
        tileBusy[t].store(false);
        // A chunk published after the loop's last check but before the release found the tile
        // busy; its task has returned, so this thread takes the chunk.
        if (next >= published.load()) return;
    }
}

void PenumbraCaster::setProgress(CastProgress progress) { impl_->progress = std::move(progress); }

void PenumbraCaster::cast(std::span<const Triangle> blockers) {
    Impl& m = *impl_;
    if (!m.started) m.castWatch.reset(), m.started = true;
    const uint64_t c = m.published.load();
    BlockerBatch& batch = *m.ring[c % m.ring.size()];
    // The slot still holds chunk c - ring size until every tile has cast it and the last has
    // counted its root culls. Rather than wait, this thread casts the tiles nobody holds; it
    // yields only while the tiles that still need the slot run on other threads.
    while (batch.inUse.load()) {
        for (size_t t = 0; t < m.tiles.size() && !m.failed && batch.inUse.load(); ++t) m.drain(t, 1);
        if (m.failed) m.group.wait();  // rethrows the tile's exception
        if (batch.inUse.load()) std::this_thread::yield();
    }
    m.stats.closedBackFaces += m.culls->prepare(batch, blockers);
    batch.reached.resize(m.tiles.size() * batch.n);
    batch.remaining.store(int(m.tiles.size()));
    batch.inUse.store(true);
    m.published.store(c + 1);
    for (size_t t = 0; t < m.tiles.size(); ++t) m.group.run([&m, t] { m.drain(t); });
    m.stats.trianglesProcessed += blockers.size();
}

void PenumbraCaster::flush() {
    Impl& m = *impl_;
    if (!m.started) return;
    m.group.wait();  // every publish ran drain() for every tile, so every tile is caught up
    m.started = false;
    // Wall time from the first chunk to the last tile: includes whatever the caller did between
    // chunks (reading the replay), which the tiles overlapped.
    m.stats.castSeconds += m.castWatch.seconds();
    m.stats.trianglesCulledAtRoot = m.culledAtRoot.load();
}

void PenumbraCaster::finish(const MaskVisitor& visit, const std::function<void(uint64_t)>& visited) {
    flush();
    // Shading every receiver is a few percent of a bake, and most of it under a light of
    // thousands of samples; done on one thread it was most of the time outside the cast.
    // Receivers are independent, so visits run in parallel.
    tbb::parallel_for(size_t(0), impl_->tiles.size(), [&](size_t t) {
        const TileCaster& tile = *impl_->tiles[t];
        const ReceiverHierarchy& h = tile.hierarchy();
        tbb::parallel_for(tbb::blocked_range<size_t>(0, h.retired.size(), 1024), [&](const tbb::blocked_range<size_t>& range) {
            for (size_t i = range.begin(); i != range.end(); ++i) visit(h.retired[i], nullptr, true);
            if (visited) visited(range.size());
        });
        tbb::parallel_for(tbb::blocked_range<size_t>(0, h.liveCount(), 1024), [&](const tbb::blocked_range<size_t>& range) {
            for (size_t r = range.begin(); r != range.end(); ++r) {
                if (h.fullUmbra[r]) visit(h.id[r], nullptr, true);
                else visit(h.id[r], h.mask[r] != MaskPool::kNone ? tile.pool().data(h.mask[r]) : nullptr, false);
            }
            if (visited) visited(range.size());
        });
    });
}

size_t PenumbraCaster::preparedChunkBytes(size_t lights) { return BlockerBatch::bytes(kTriangleChunk, lights); }

CastStats PenumbraCaster::stats() const {
    CastStats s = impl_->stats;
    for (const SampleMaskTable& table : impl_->tables) s.sampleTableBytes += table.bytes();
    for (const auto& tile : impl_->tiles) {
        const TileStats& t = tile->stats();
        s.hierarchyBuildSeconds += t.buildSeconds;
        s.rebuilds += t.rebuilds;
        s.peakLiveMasks += tile->pool().peakLive();
        s.peakMaskBytes += tile->pool().peakLive() * size_t(tile->pool().words()) * sizeof(uint64_t);
        s.peakHierarchyBytes += t.peakHierarchyBytes;
        s.receiverBytes += t.peakReceiverBytes;
        s.hardShadowTests += t.hardTests;
        s.tableDecidedRelations += t.tableDecided;
        s.alphaTests += t.alphaTests;
        s.alphaRejected += t.alphaRejected;
        s.alphaGroupTests += t.alphaGroupTests;
        s.alphaGroupsDecided += t.alphaGroupsDecided;
    }
    return s;
}

}  // namespace penumbra
