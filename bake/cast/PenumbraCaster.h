#pragma once
/// @file PenumbraCaster.h
/// @brief Hierarchical penumbra casting (Laine & Aila 2005) over tiles of receivers: the public
/// face of the method. The traversal of Figure 3 is TileCaster.h; the root culls and V_L are
/// BlockerBatch.h; this class cuts the receivers into tiles and schedules chunks of blockers
/// over them.

#include "bake/cast/CastOptions.h"
#include "bake/light/Light.h"
#include "receivers/ReceiverSet.h"
#include "stream/Triangle.h"

#include <functional>
#include <memory>
#include <span>
#include <vector>

namespace penumbra {

/// @brief Called once per receiver when a cast finishes. @p groupWords holds one word per light
/// sample group (bit j of word k: sample groups[k].first + j is blocked); it is nullptr when no
/// relation of the receiver is blocked. @p fullUmbra means every sample is blocked.
using MaskVisitor = std::function<void(uint32_t receiver, const uint64_t* groupWords, bool fullUmbra)>;

/// @brief Called from the threads that cast each time a tile finishes a chunk: @p triangles is
/// that tile's share of the chunk's count (the shares of all tiles add up to it exactly) and
/// @p work the units the tile spent on it not reported yet (TileCaster::work()). Within a chunk it
/// is also called every few hundred blockers with @p triangles 0 and the work spent so far, so the
/// work moves while a heavy chunk is cast. Must not throw; it runs inside the tiles' tasks.
using CastProgress = std::function<void(uint64_t triangles, uint64_t work)>;

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
    /// @brief Reports finished work to @p progress from now on (before the first cast()).
    void setProgress(CastProgress progress);
    /// @brief Waits until every tile has cast every chunk; rethrows a tile's exception.
    void flush();
    /// @brief Flushes, then reports every receiver's result to @p visit exactly once. Visits run
    /// in parallel, so @p visit must be safe to call concurrently for different receivers.
    /// @param visited when given, called with the count of each block of receivers visited
    ///        (up to a thousand at a time, concurrently): the shading's progress.
    void finish(const MaskVisitor& visit, const std::function<void(uint64_t)>& visited = {});

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
    struct Impl;  // tiles, tables, culls and the ring of prepared chunks (PenumbraCaster.cpp)
    std::unique_ptr<Impl> impl_;
};

/// @brief Splits receivers into @p count spatially compact parts of near-equal size by recursive
/// median splits, deterministic in the input.
std::vector<std::vector<uint32_t>> partitionReceivers(const ReceiverSet& receivers, std::span<const uint32_t> ids,
                                                      int count);

}  // namespace penumbra
