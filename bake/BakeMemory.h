#pragma once
/// @file BakeMemory.h
/// @brief The memory side of a bake, as the pipeline checks it: what the budget is (the
/// `--memory-budget`, or what an address-space limit leaves), and what the bake needs before
/// its scan pass (worst case) and after it (exact).
///
/// Order of checks, so that a failure comes before any work and names a budget that works:
/// 1. Before the scan: the demand with the most receivers the kind can make (a camera's pixels)
///    and the most its tables can grow to. A budget below what the scan pass itself needs fails
///    here, naming that worst-case minimum, which is sure to be enough.
/// 2. After the scan (before the bucket pass and the cast): the demand with the receivers found,
///    exact up to the kind's bound on its tables; a failure names the smallest budget that works.
/// Later plans only see smaller or equal demands, so they cannot fail again. The antialiasing
/// pass, whose pixels depend on the first cast's results, is checked once when they are known,
/// before its pass: the pass, then its cast and the outputs with every sub-pixel sample a receiver
/// (MemoryDemand::Refinement), so that it fails at most once, naming a budget that works.

#include "bake/cast/Caster.h"
#include "bake/light/Light.h"
#include "bake/MemoryPlan.h"
#include "bake/kinds/ReceiverKind.h"
#include "bake/Scene.h"
#include "stream/TriangleSource.h"

#include <cstdint>
#include <string>

namespace penumbra {

/// @brief The budget a bake plans with.
struct BakeBudget {
    uint64_t bytes = 0;  ///< 0: unlimited
    /// Address space already spent before any bake data (libraries, stacks), added back in
    /// messages about an address-space limit.
    uint64_t overhead = 0;
    /// Added to the limit a refusal names: the stacks of the threads the limit had no room for
    /// (under the named limit all of them run), and what is mapped moving by a MiB or so from one
    /// limit to the next. A limit named without them was refused again (200M named 240M, then 244M).
    uint64_t namedSlack = 0;
    std::string label = "--memory-budget";
    int threads = 1;  ///< threads that cast: each holds sub-tiles (MemoryDemand::threads)
    int threadsWanted = 1;  ///< threads asked for, before an address-space limit lowered them
    /// The scene, named before an address-space limit's refusals (a --memory-budget one names the
    /// option, which is enough).
    std::string where;

    /// What a refusal starts with: "--memory-budget", or "SCENE: the address-space limit ... of".
    std::string subject() const { return where.empty() || label == "--memory-budget" ? label : where + ": " + label; }
    MemoryPlan plan(const MemoryDemand& demand) const { return planMemory(demand, bytes, subject(), overhead, namedSlack); }
    /// Whether the budget is the process's address-space limit (not a --memory-budget within it).
    bool addressSpace() const { return label != "--memory-budget"; }
};

/// @brief checkBeforeScan()'s refusal under an address-space limit with more than one thread:
/// each thread fewer frees a stack and a thread's sub-tiles, so the bake is tried again on fewer
/// (runBake()) before it is refused.
struct ThreadsDoNotFit : InputError {
    ThreadsDoNotFit(const std::string& message, int fewer) : InputError(message), threads(fewer) {}
    int threads;  ///< the most threads whose freed stacks would make up the shortfall (at least 1)
};

/// Stack reserved per TBB worker (set through tbb::global_control) and per read-ahead thread.
inline constexpr uint64_t kWorkerStackBytes = 4ull << 20;
inline constexpr uint64_t kReadAheadStackBytes = 8ull << 20;
/// What the kernel reports as mapped moves by about a MiB between runs under different limits.
inline constexpr uint64_t kMappedJitterBytes = 2ull << 20;

/// @brief The budget for @p memoryBudget under this process's address-space limit, if any: with a
/// limit, malloc keeps one arena, thread stacks and what is already mapped are set aside, and
/// @p threads is lowered (with a warning unless @p quiet) until a bake can fit.
/// @param wanted the threads first asked for (0: @p threads), named by the warning
BakeBudget fitAddressSpace(uint64_t memoryBudget, int& threads, bool quiet, int wanted = 0);
/// @brief The warning of a lowered thread count, when @p budget's threads are fewer than wanted.
void warnFewerThreads(const BakeBudget& budget, bool quiet);

/// @brief The demand known before the scan pass: the kind's scan buffers and worst cases, the
/// opened sources' working sets, light samples and fixed buffers.
/// @param methodMemory the method's own memory (CasterEntry::memory), counted when the geometry
///        knows its triangle count before it is read: a budget named without it was refused
///        again after the scan by ssv and embree.
/// @param alpha false: leave out the glTF cut-out tables, whose plan parses the files' JSON.
MemoryDemand demandBeforeScan(const SceneDesc& scene, const ReceiverKind& kind, const TriangleSource& geometry, MaskKeeping masks,
                              const CasterMemory& methodMemory = {},
                              bool alpha = true);

/// @brief Sets the sample groups and sample bytes (positions and sample mask tables) of @p samples.
void addSampleDemand(MemoryDemand& demand, const LightSamples& samples, const SceneDesc& scene);

/// @brief Check 1 above. @throw InputError naming the worst-case minimum (ThreadsDoNotFit under
/// an address-space limit with more than one thread).
void checkBeforeScan(const MemoryDemand& demand, const BakeBudget& budget);

/// @brief The least budget or limit a refusal before the scan names for @p demand: the plan's
/// worst case, and under an address-space limit what the scan pass will find mapped and the
/// stacks of the threads the limit left no room for.
uint64_t leastNamedLimit(const MemoryDemand& demand, const BakeBudget& budget);

/// @brief Opens the scene's geometry as a bake does before its scan, and makes check 1: a texture
/// that alone does not fit @p budget is refused before it is decoded, then the sources are opened
/// (a large OBJ's check pass shown as a phase unless @p quiet: OpeningProgress) and the demand
/// before the scan is checked. Shared by the bake and `penumbra slurm`, which runs it for its shards.
/// @param masks whose masks are kept once cast (a dump, a shard file, checkpoints)
/// @param demand set to demandBeforeScan()
/// @return the opened geometry
/// @throw InputError as checkSceneAlphaBudget(), the sources and checkBeforeScan()
TriangleSourcePtr openCheckedBeforeScan(const SceneDesc& scene, const ReceiverKind& kind, const BakeBudget& budget, MaskKeeping masks,
                                        bool quiet, MemoryDemand& demand,
                                        const CasterMemory& methodMemory = {});

}  // namespace penumbra
