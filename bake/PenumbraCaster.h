#pragma once
/// @file PenumbraCaster.h
/// @brief Hierarchical penumbra casting (Laine & Aila 2005, Figure 3) over tiles of receivers.

#include "bake/BlockingRule.h"
#include "bake/CastOptions.h"
#include "bake/PenumbraVolume.h"
#include "bake/ReachHull.h"
#include "bake/Light.h"
#include "bake/SampleMaskTable.h"
#include "receivers/ReceiverSet.h"
#include "stream/Triangle.h"

#include <tbb/task_group.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <span>
#include <vector>

namespace penumbra {

/// @brief Called once per receiver when a cast finishes. @p groupWords holds one word per light
/// sample group (bit j of word k: sample groups[k].first + j is blocked); it is nullptr when no
/// relation of the receiver is blocked. @p fullUmbra means every sample is blocked.
using MaskVisitor = std::function<void(uint32_t receiver, const uint64_t* groupWords, bool fullUmbra)>;

/// @brief Receivers are split spatially into tiles, each with its own hierarchy and mask pool.
/// Tiles are independent, so they are cast in parallel and the result does not depend on the
/// tile count or the thread count. Blocker order does not change the result either: a mask is
/// the OR over all blockers.
class PenumbraCaster {
public:
    /// @param receiverIds which receivers of @p receivers to cast (all when empty)
    /// @param tiles how many spatial tiles to cut the receivers into (>= 1)
    PenumbraCaster(const LightSamples& samples, const ReceiverSet& receivers, std::span<const uint32_t> sampleSetOf,
                   const CastOptions& options, int tiles, std::span<const uint32_t> receiverIds = {});
    ~PenumbraCaster();

    /// @brief Casts a chunk of blockers (in the order given) against every tile. The chunk is
    /// copied and prepared on the calling thread, then cast by the tiles in the background; when
    /// the ring of prepared chunks is full, the calling thread casts tiles until a slot is free.
    void cast(std::span<const Triangle> blockers);
    /// @brief Waits until every tile has cast every chunk; rethrows a tile's exception.
    void flush();
    /// @brief Flushes, then reports every receiver's result to @p visit exactly once. Visits run
    /// in parallel, so @p visit must be safe to call concurrently for different receivers.
    void finish(const MaskVisitor& visit);

    /// @brief Counters and timers; call after finish() or flush() to include the last chunk.
    CastStats stats() const;

    /// @brief Chunks of prepared blockers held at once: two with one tile (one prepared while
    /// the other is cast), kMaxRingChunks with several.
    static size_t ringChunks(size_t tiles) { return tiles > 1 ? kMaxRingChunks : 2; }
    static constexpr size_t kMaxRingChunks = 3;
    /// @brief Bytes of one prepared chunk of kTriangleChunk blockers, for memory planning. The
    /// flags of which tiles a blocker reached (a byte per blocker and tile) are left out, so that
    /// a plan, and so a tiled bake, does not depend on the thread count.
    static size_t preparedChunkBytes(size_t lights);

private:
    struct Tile;
    const LightSamples& samples_;
    CastOptions options_;
    std::vector<std::unique_ptr<Tile>> tiles_;
    std::vector<SampleMaskTable> tables_;  ///< per light when options_.sampleTable; shared by tiles
    CastStats stats_;
    /// Per light: the box around the light's bound and every receiver. A blocker can only block a
    /// segment from a receiver to a sample if it meets their convex hull, so a blocker whose box
    /// misses this box is culled before its penumbra volume is built.
    std::vector<Box> reach_;
    /// Per light: the hull of a ball around the light and one around the receivers (ReachHull.h),
    /// the finer second test for blockers inside reach_.
    std::vector<ReachHull> reachHull_;
    Box receiversBox_;  ///< around every tile's receivers
    /// A chunk of blockers ready to cast: promoted to double, with V_L per light, and which tiles
    /// still have to cast it. Kept in a ring so tiles need not wait for one another: each tile
    /// casts the chunks in order at its own pace, and a tile may run up to the ring's length
    /// behind the others (the per-chunk barrier this replaces left a thread idle at the end of
    /// every chunk). Buffers are kept to avoid reallocation.
    struct Batch {
        size_t n = 0;
        std::vector<BlockerTriangle> prepared;
        std::vector<PenumbraVolume> lightVolumes;  ///< [triangle][light]
        std::vector<uint8_t> lightActive;          ///< [triangle][light]: in reach and not capped away
        std::vector<uint8_t> reached;              ///< [tile][triangle]: V_L met the tile's root box
        std::atomic<int> remaining{0};             ///< tiles that have not cast this chunk yet
    };
    std::vector<std::unique_ptr<Batch>> ring_;
    std::atomic<uint64_t> published_{0};  ///< chunks prepared and handed to the tiles
    /// Per tile: the next chunk it casts. Only the holder of the tile's busy flag touches it.
    std::vector<uint64_t> tileNext_;
    std::unique_ptr<std::atomic<bool>[]> tileBusy_;
    std::atomic<bool> failed_{false};  ///< a tile threw; flush() rethrows it
    std::atomic<uint64_t> culledAtRoot_{0};
    tbb::task_group group_;
    bool started_ = false;
    std::chrono::steady_clock::time_point castStart_;

    void prepare(Batch& batch, std::span<const Triangle> blockers);
    /// Casts every published chunk that tile @p t has not cast yet, unless another thread holds
    /// the tile (that thread then sees the new chunks before it lets go).
    void drain(size_t t);
    /// The tile's part of a chunk; the last tile to finish it counts the chunk's root culls.
    void castOnTile(size_t t, Batch& batch);
};

/// @brief Splits receivers into @p count spatially compact parts of near-equal size by recursive
/// median splits, deterministic in the input.
std::vector<std::vector<uint32_t>> partitionReceivers(const ReceiverSet& receivers, std::span<const uint32_t> ids,
                                                      int count);

}  // namespace penumbra
