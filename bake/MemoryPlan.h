#pragma once
/// @file MemoryPlan.h
/// @brief Checks a bake against `--memory-budget` before it starts and decides how many receiver
/// tiles to process one after another. Memory is receivers + masks + fixed buffers + each
/// source's bounded working set (glTF documents, block caches, decoders); triangles never count,
/// because they stream.
///
/// Phases, each checked: the scan pass (the receiver kind's scan buffers and the sources), the
/// bucket pass (resident data and the sources), the cast (resident data and one tile), and the
/// output stage (resident data and the kind's writer, camera images in strips). The smallest
/// budget that works is the largest of them with one smallest tile.

#include <cstdint>
#include <string>

namespace penumbra {

/// @brief Whose masks a bake keeps whole once they are cast (a dump, a shard file, checkpoints,
/// a library caller).
struct MaskKeeping {
    bool kept = false;
    /// > 1: a by-receivers shard of this many keeps its share's only, at most ceil(receivers /
    /// shares) rows (receiverSharesBeforeScan(); MemoryDemand::castReceivers once it is known).
    uint32_t shares = 1;
};

/// @brief What the plan needs to know about a bake.
struct MemoryDemand {
    uint64_t receivers = 0;      ///< receivers (0 before the camera pass has counted them)
    uint64_t castReceivers = 0;  ///< receivers the first pass casts (a by-receivers shard's share); 0: all
    uint64_t maskRows = 0;       ///< masks kept for this many receivers only (that share; MaskKeeping); 0: all
    /// Held by each sub-tile of a memory tile whatever its receivers (TileCaster::fixedBytes):
    /// a memory tile is cast by subTiles() of them at once.
    uint64_t subTileBytes = 0;
    int threads = 1;             ///< threads that cast
    uint64_t scanBytes = 0;      ///< held by the receiver kind during the scan pass (z-buffer + receiver set)
    uint64_t outputBytes = 0;    ///< held by the receiver kind while writing its outputs
    int groups = 1;              ///< light-sample groups: mask words per receiver
    int umbraWords = 1;          ///< ceil(groups / 64)
    uint64_t sampleBytes = 0;    ///< light sample positions
    /// Held while the samples are generated, before the scan reads anything: their positions and
    /// the light bounds' copies of every set's points and their hull (about 100 bytes a position).
    uint64_t sampleBuildBytes = 0;
    /// Masks are kept once cast (MaskKeeping): every receiver's, or with maskRows below receivers
    /// a by-receivers shard's share and a row index per receiver (VisibilityMasks).
    bool dumpMasks = false;
    uint64_t bufferBytes = 0;    ///< bucket buffers, chunks and other fixed buffers
    uint64_t kindBytes = 0;      ///< held by the receiver kind through casting (smooth shading's vertex table, a refinement pass)
    uint64_t methodBytes = 0;    ///< held by the method while it casts (CasterEntry::memory: a ray caster's scene)
    uint64_t sourceBytes = 0;    ///< the geometry sources' working set while they stream (TriangleSource::residentBytes)
    std::string sourceDetail;    ///< what dominates sourceBytes, for the message (a large compressed primitive)
    bool sourceDuringCast = false;  ///< the sources are replayed by the cast (no bucket files)
    uint64_t alphaBytes = 0;       ///< the alpha table of glTF cut-outs (1-bit maps, entries, ids), held for the whole bake
    uint64_t alphaBuildBytes = 0;  ///< held while it is built before the scan (a texture's decode, the deduplication index)
    /// Translucent blockers held for the bake (bake/cast/TranslucentBlockers.h), at worst every
    /// alpha-matte triangle, and each thread's row of per-sample depths.
    uint64_t translucentBytes = 0;
    /// Set for the check before a refinement's pass (camera antialiasing, once its pixels are
    /// known): the receivers it may add at most, and the kind's resident and output bytes with
    /// them. planMemory() folds the bake after that pass (every receiver resident, a smallest tile
    /// cast, the outputs written) into the minimum budget, so that one check covers the rest of
    /// the bake; the tiles stay those of the receivers cast so far.
    struct Refinement {
        uint64_t addedReceivers = 0;
        uint64_t kindBytesAfter = 0;
        uint64_t outputBytesAfter = 0;
    } refinement;
};

struct MemoryPlan {
    uint64_t budget = 0;           ///< 0: unlimited
    uint64_t residentBytes = 0;    ///< held for the whole bake (receivers, results, buffers, baseline)
    uint64_t perReceiverBytes = 0; ///< hierarchy + worst-case mask of one receiver in a tile
    int tiles = 1;                 ///< receiver tiles processed one after another
    /// Sub-tiles per thread within a memory tile (HpcCaster): 4 evens the threads' work out; fewer
    /// when their fixed bytes (MemoryDemand::subTileBytes) would take more than half the room.
    int subTilesPerThread = 4;
    uint64_t minimumBudget = 0;    ///< the smallest budget that works (one smallest tile)
    /// What a budget leaves beyond the plan's peak while casting and writing (0 without one):
    /// room for caches that speed the cast up but need not be planned (the translucent pass's).
    uint64_t spareBytes = 0;
};

/// @brief Sub-tiles alive at once while a memory tile is cast with @p perThread per thread: one
/// with one thread, and the caster of the closed faces' exempt receivers (one more).
inline uint64_t subTilesAtOnce(int threads, int perThread) { return (threads > 1 ? uint64_t(perThread) * uint64_t(threads) : 1) + 1; }

/// @brief Bytes of the masks @p d keeps whole once cast (MemoryDemand::dumpMasks).
uint64_t keptMaskBytes(const MemoryDemand& d);

/// Bytes the process needs before any bake data (code, libraries, thread stacks, allocator). A
/// small bake peaks at 15-17 MiB in all, so the baseline also holds the few fixed buffers no
/// phase names, such as the scan's closed-solid check (kSolidCheckBytes, 6.25 MiB at most) and,
/// in a bake without a budget, the translucent pass's cached blocks (8 MiB at most).
inline constexpr uint64_t kBaselineBytes = 48ull << 20;
/// A tile is never cut smaller than this many receivers.
inline constexpr uint64_t kMinimumTileReceivers = 4096;

/// @brief Plans tiles for @p budget bytes (0 = unlimited: one tile).
/// @throw InputError when even one smallest tile does not fit, naming the smallest budget that
/// would, rounded up to a whole MiB so it can be given as it is ("--memory-budget 64.0 MiB is too
/// small for 2073600 receivers of 4 light-sample groups each; at least 310M is needed").
/// @param label and @p overhead name the limit in the message: a budget derived from an
///        address-space limit says so, and counts what the process had mapped before.
/// @param namedSlack added to the limit the message names (BakeBudget::namedSlack).
MemoryPlan planMemory(const MemoryDemand& demand, uint64_t budget, const std::string& label = "--memory-budget",
                      uint64_t overhead = 0, uint64_t namedSlack = 0);

/// @brief The phase the scan pass needs (the receiver kind's scan buffers and the sources), which
/// must fit before anything is read.
uint64_t scanPhaseBytes(const MemoryDemand& demand);

/// @brief @p bytes rounded up to a whole MiB, as a --memory-budget value: "109M".
std::string budgetText(uint64_t bytes);
/// @brief A budget that was refused, for the same messages: whole MiB as "103 MiB", else rounded
/// down to a tenth ("102.7 MiB"; under 1 MiB as formatBytes()), so that it never reads as the amount named as enough.
std::string refusedBudgetText(uint64_t bytes);

}  // namespace penumbra
