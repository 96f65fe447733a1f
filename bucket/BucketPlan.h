#pragma once
/// @file BucketPlan.h
/// @brief The bucket pass in one call: choose area ranges, stream a source into bucket files,
/// report what it cost.
///
/// Typical use in a bake (two passes over the source at most):
///
///     AreaHistogram histogram;                        // pass 1, if there is one anyway:
///     ... histogram.add(chunk) while rasterizing ...  //   camera receivers
///     BucketRanges ranges = planBucketRanges(options, &histogram);  // or nullptr: fixed log2
///     source.rewind();
///     BucketStats stats;
///     auto set = std::make_shared<BucketSet>(writeBuckets(source, ranges, options, &stats));  // pass 2
///     BucketReplaySource replay(set, options.readBufferBytes);  // once per tile, rewind() between

#include "bucket/AreaHistogram.h"
#include "bucket/BucketFiles.h"
#include "bucket/BucketOptions.h"
#include "bucket/BucketRanges.h"
#include "stream/TriangleSource.h"

#include <cstdint>
#include <functional>
#include <span>

namespace penumbra {

/// @brief What the bucket pass did, for --stats.
struct BucketStats {
    uint64_t triangles = 0;
    uint64_t opaqueTriangles = 0;
    uint64_t alphaMatteTriangles = 0;
    uint64_t bytesWritten = 0;
    uint64_t culledTriangles = 0;  ///< read but dropped by the filter: never written
    size_t ranges = 0;          ///< area ranges (buckets per kind)
    size_t nonEmptyFiles = 0;   ///< bucket files holding at least one triangle
    double seconds = 0;         ///< the whole pass: reading the source, sorting into buckets, writing
    double writeSeconds = 0;    ///< the part inside BucketWriter (classify, copy, write(2), flush)

    /// Bytes written per second of writing (writeSeconds), in MB/s (10^6 bytes). Of the whole
    /// pass it read 0-1 MB/s whenever the cull before spill dropped most triangles: the pass is
    /// mostly reading and culling the source then.
    double megabytesPerSecond() const { return writeSeconds > 0 ? double(bytesWritten) / 1e6 / writeSeconds : 0.0; }
    /// Bucket bytes per triangle (40 for raw records).
    double bytesPerTriangle() const { return triangles ? double(bytesWritten) / double(triangles) : 0.0; }
};

/// @brief Chooses the area ranges: histogram quantiles when @p histogram holds any areas,
/// fixed log2 ranges below @p largestAreaHint otherwise (see AreaHistogram for the trade-off).
/// @throw InputError when options.buckets is out of range.
BucketRanges planBucketRanges(const BucketOptions& options, const AreaHistogram* histogram,
                              float largestAreaHint = 1.0f);

/// @brief Reads @p source from its current position to the end into bucket files.
/// @param source read in kTriangleChunk chunks; left at its end (not rewound).
/// @param ranges the area ranges (planBucketRanges()).
/// @param options directory, keep, buffer sizes.
/// @param stats when given, filled in (also on success only).
/// @param onChunk when given, sees every chunk before it is bucketed (all of it, before @p keep):
///        a hook for checks (finite coordinates) or progress that would otherwise need a pass of
///        their own.
/// @param keep when given, only triangles it returns true for are written (the reach cull of
///        bake/ReachCull.h: what cannot block is never written to disk). Chunks are filtered
///        on several threads at once, so it must be safe to call concurrently (a pure function of
///        the triangle); the files do not depend on the thread count. @p onChunk and the source
///        are called one chunk at a time, in stream order, but not always on the caller's thread.
/// @return the finished set; wrap it in a shared_ptr for BucketReplaySource.
/// @throw InputError from the source, from @p onChunk, or from BucketWriter (full disk, file-size
///        limit, unusable temp directory); no bucket file or directory remains afterwards.
BucketSet writeBuckets(TriangleSource& source, const BucketRanges& ranges, const BucketOptions& options,
                       BucketStats* stats = nullptr,
                       const std::function<void(std::span<const Triangle>)>& onChunk = {},
                       const std::function<bool(const Triangle&)>& keep = {});

}  // namespace penumbra
