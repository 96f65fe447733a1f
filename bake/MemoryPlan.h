#pragma once
/// @file MemoryPlan.h
/// @brief Checks a bake against `--memory-budget` before it starts and decides how many receiver
/// tiles to process one after another. Memory is receivers + masks + fixed buffers; triangles
/// never count, because they stream.

#include <cstdint>
#include <string>

namespace penumbra {

/// @brief What the plan needs to know about a bake.
struct MemoryDemand {
    uint64_t receivers = 0;      ///< receivers (0 before the camera pass has counted them)
    uint64_t scanBytes = 0;      ///< held by the receiver kind during the scan pass (z-buffer + receiver set)
    uint64_t outputBytes = 0;    ///< held by the receiver kind while writing its outputs
    int groups = 1;              ///< light-sample groups: mask words per receiver
    int umbraWords = 1;          ///< ceil(groups / 64)
    uint64_t sampleBytes = 0;    ///< light sample positions
    bool dumpMasks = false;      ///< --dump keeps every receiver's final mask
    uint64_t bufferBytes = 0;    ///< bucket buffers, chunks and other fixed buffers
    uint64_t kindBytes = 0;      ///< held by the receiver kind through casting (smooth shading's vertex table, a refinement pass)
    uint64_t sceneBytes = 0;     ///< a method that holds the scene in memory (ssv: faces, edges, kd-trees); hpc streams: 0
};

struct MemoryPlan {
    uint64_t budget = 0;           ///< 0: unlimited
    uint64_t residentBytes = 0;    ///< held for the whole bake (receivers, results, buffers, baseline)
    uint64_t perReceiverBytes = 0; ///< hierarchy + worst-case mask of one receiver in a tile
    int tiles = 1;                 ///< receiver tiles processed one after another
    uint64_t minimumBudget = 0;    ///< the smallest budget that works (one smallest tile)
};

/// Bytes the process needs before any bake data (code, libraries, thread stacks, allocator).
inline constexpr uint64_t kBaselineBytes = 48ull << 20;
/// A tile is never cut smaller than this many receivers.
inline constexpr uint64_t kMinimumTileReceivers = 4096;

/// @brief Plans tiles for @p budget bytes (0 = unlimited: one tile).
/// @throw InputError when even one smallest tile does not fit, naming the smallest budget that
/// would ("--memory-budget 64M is too small for 2,073,600 receivers and 4 mask words; at least
/// 310M is needed").
MemoryPlan planMemory(const MemoryDemand& demand, uint64_t budget);

}  // namespace penumbra
