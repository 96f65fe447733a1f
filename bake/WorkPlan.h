#pragma once
/// @file WorkPlan.h
/// @brief What a bake will need of the machine, checked before the work that needs it: memory
/// against what the machine has, bucket files against the free space of `--tmp`, and time. A
/// request that cannot fit is refused before any work with the numbers (a 65536² camera's
/// z-buffer, the 344 GB of bucket files of a 65536² terrain on an 80 GB disk); one that fits but
/// will take hours says so up front, with the estimate (`--quiet` keeps that quiet).
///
/// The memory needed comes from the memory plan (MemoryPlan.h: its smallest budget that works);
/// the machine's memory is its physical memory plus swap, or less under a cgroup limit.

#include "bake/MemoryPlan.h"

#include <cstdint>
#include <optional>
#include <string>

namespace penumbra {

/// @brief Physical memory plus swap, capped by the cgroup's memory.max when there is one; 0 when
/// unknown (no check is made then).
uint64_t machineMemoryBytes();

/// @brief Bytes free for an unprivileged writer on the file system of @p dir; 0 when unknown.
uint64_t freeDiskBytes(const std::string& dir);

/// @brief Refuses, before the work, a phase that needs @p neededBytes more address space than an
/// address-space limit leaves now, asking the kernel rather than trusting the plan's estimate of
/// what is mapped already (a tight `prlimit --as` would otherwise end in a failed allocation, or
/// a thread that cannot start, in the middle of the scan).
/// @param wholeBake the least limit the rest of the bake may ask for at its worst (0: unknown);
///        when it is the larger, the refusal names it as sure to do and the phase's own need beside
///        it, so that the limit named is not refused again by a later phase.
/// @throw InputError naming @p scene and the least limit that works.
void checkAddressSpaceLeft(const std::string& scene, const char* what, uint64_t neededBytes, uint64_t wholeBake = 0);

/// @brief The least address-space limit under which a phase needing @p neededBytes more can start
/// now: what the kernel says is mapped, the phase, and the read-ahead thread's reserve (the
/// number checkAddressSpaceLeft() names).
uint64_t addressSpaceNeeded(uint64_t neededBytes);

/// @brief Refuses a bake whose smallest workable memory, @p neededBytes, exceeds
/// machineMemoryBytes(). @p what says which phase needs it ("the scan pass", "casting").
/// @throw InputError "SCENE: the scan pass needs at least 64.0 GiB of memory, but this machine has
///        23.4 GiB (physical memory and swap) ...".
void checkMemoryFits(const std::string& scene, const char* what, uint64_t neededBytes);

/// @brief Refuses a bake whose bucket files (40 bytes per triangle of @p triangles, when @p sort)
/// cannot fit in the free space of @p tmpDir ("" = the system temp directory). With @p mayCull
/// (cull before spill will drop the blockers out of every light's reach, a count known only
/// during the bucket pass) that is only an upper bound: a warning then, and the bucket pass
/// stops cleanly if the disk does fill (BucketWriter).
/// @throw InputError "--tmp /tmp: the bucket files of 8590007494 triangles need 320 GiB, but it
///        has 75.2 GiB free ...".
void checkBucketDisk(const std::string& tmpDir, std::optional<uint64_t> triangles, bool sort, bool mayCull = false);

/// @brief The plan's estimate of a bake's wall time: every triangle is streamed `2 + tiles` times
/// (scan, buckets, one cast per memory tile), at kSecondsPerTrianglePass per pass and thread.
double estimatedSeconds(uint64_t triangles, int tiles, int threads);

/// CPU seconds per triangle and pass, from meadow-1b (docs/BENCHMARKS.md: 1,040 CPU s for
/// 1.0G triangles in three passes).
inline constexpr double kSecondsPerTrianglePass = 0.35e-6;

/// CPU seconds per receiver and light sample that shading them takes at least, whatever the
/// triangles: a 2048² lightmap of 3.9M texels under 256 samples took 47 CPU s (0.05 µs), so a
/// bake of many receivers is announced even when its scene is small.
inline constexpr double kSecondsPerReceiverSample = 0.04e-6;

/// @brief Prints a note with the estimate when it is an hour or more (unless @p quiet): the
/// triangle passes (estimatedSeconds), or @p receivers x @p samples at kSecondsPerReceiverSample
/// when that is more.
void noteLongBake(uint64_t triangles, uint64_t receivers, uint64_t samples, int tiles, int threads, bool quiet);

}  // namespace penumbra
