#pragma once
/// @file AreaHistogram.h
/// @brief Distribution of triangle areas, and the two ways of choosing bucket area ranges.
///
/// The coarse blocker sort (Laine & Aila 2005, Section 3.3) only needs buckets whose ranges
/// decrease; how well it works depends on how evenly the triangles spread over them. There are
/// two ways to choose the ranges, and the choice decides how many passes the source needs:
///
///  - **Quantile buckets** (bucketBoundaries()): split points at quantiles of the measured area
///    distribution, so every bucket holds about the same number of triangles whatever the
///    scene's scale or skew. This needs the histogram before the bucket pass, i.e. one pass over
///    the source first. A bake with camera receivers already makes that pass (it rasterizes all
///    geometry to find the receivers), so feeding each chunk to add() there makes the histogram
///    free, and the total stays at two passes: rasterize + histogram, then bucket.
///  - **Fixed log2 buckets** (fixedLog2Boundaries()): split points at powers of two below a
///    reference area, one (or more) octave per bucket. No pre-pass at all, so a bake with point
///    receivers (which need no rasterization) reads its source exactly once. The price: a scene
///    whose areas sit in a few octaves uses only a few buckets, and a scene far from the
///    reference scale piles into the first or last bucket. The sort stays correct either way;
///    only how early big occluders are found suffers.
///
/// Bins are 64 per octave and come straight from the float's bit pattern: the 8 exponent bits
/// and the top 6 mantissa bits of a positive float, 14 bits in all, index one of 16384 bins.
/// So the bin of an area is one shift, bins are monotone in area, every bin edge is an exactly
/// representable float, and a split point placed on a bin edge classifies triangles exactly as
/// the histogram counted them. Within an octave the 64 bins are linear in area (each spans 1/64
/// of the octave's lower edge), which is within 1.6% of log spacing and good enough for a sort.
/// The table is 128 KiB; merge() combines per-thread histograms.

#include "bucket/BucketRanges.h"
#include "stream/Triangle.h"
#include "stream/TriangleSource.h"

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

class AreaHistogram {
public:
    /// Bins per octave of area (a power of two; see the file comment).
    static constexpr int kBinsPerOctave = 64;
    /// A non-negative float's bits shifted right by this keep the exponent and 6 mantissa bits.
    static constexpr int kShift = 23 - 6;
    /// Total bins: every non-negative float bit pattern shifted right by kShift.
    static constexpr size_t kBinCount = size_t{1} << (31 - kShift);

    AreaHistogram();

    /// @brief Counts one area. NaN, negative and -0 count as 0 (see sanitizeArea()).
    void add(float area) {
        float a = sanitizeArea(area);
        ++bins_[binOf(a)];
        if (count_ == 0 || a < min_) min_ = a;
        if (count_ == 0 || a > max_) max_ = a;
        ++count_;
    }
    /// @brief Counts the area of @p triangle.
    void add(const Triangle& triangle) { add(triangle.area()); }
    /// @brief Counts the areas of a chunk (the hook for an existing pass over the source).
    void add(std::span<const Triangle> triangles) {
        for (const Triangle& t : triangles) add(t.area());
    }

    /// @brief Adds the counts of @p other (per-thread histograms reduced into one).
    void merge(const AreaHistogram& other);

    /// Areas counted so far.
    uint64_t count() const { return count_; }
    /// Smallest area counted (sanitized); 0 when empty.
    float minArea() const { return count_ ? min_ : 0.0f; }
    /// Largest area counted; 0 when empty.
    float maxArea() const { return count_ ? max_ : 0.0f; }
    /// Count in bin @p bin.
    uint64_t binCount(size_t bin) const { return bins_[bin]; }

    /// @brief The bin of a sanitized (non-negative) area: monotone, 64 bins per octave.
    static size_t binOf(float sanitizedArea);
    /// @brief The smallest area of bin @p bin; binLowerEdge(binOf(a)) <= a < binLowerEdge(binOf(a) + 1).
    static float binLowerEdge(size_t bin);

    /// @brief Split points for about @p buckets buckets holding similar numbers of triangles.
    ///
    /// Chosen greedily from the smallest areas up: each split is the bin edge nearest to an
    /// equal share of the areas still above the previous split, divided among the buckets still
    /// to place. A bin holding more than a share (a terrain of equal cells, instanced foliage)
    /// cannot be cut, so its bucket is oversized (and a neighbour may be undersized), but the
    /// rest of the distribution still gets every remaining bucket. Fewer split points come back
    /// only when there are fewer occupied bins than buckets; none ever leaves a bucket empty.
    /// @param buckets wanted bucket count, >= 1.
    /// @return ascending split points for BucketRanges; empty when the histogram is empty or all
    ///         areas share one bin (one bucket).
    /// @throw std::invalid_argument when @p buckets < 1.
    std::vector<float> bucketBoundaries(int buckets = 32) const;

    /// @brief Split points at powers of two, for a bucket pass without a histogram pre-pass.
    ///
    /// The largest bucket starts at the power of two P that is the largest not above
    /// @p largestArea (clamped to the normal float range), and each further bucket reaches
    /// @p octavesPerBucket octaves lower: splits are P, P/2^s, P/2^(2s), ... with s =
    /// octavesPerBucket, returned ascending. Anything smaller than the last split lands in the
    /// last bucket, anything larger than P in the first.
    /// @param buckets wanted bucket count, >= 1.
    /// @param largestArea where the top bucket should start: about the area of the largest
    ///        occluders expected, e.g. derived from scene bounds known up front (a .ptri
    ///        header); 1 suits metre-scale scenes when nothing is known.
    /// @param octavesPerBucket octaves covered by each bucket, >= 1: 32 buckets of 1 octave span
    ///        areas over a factor of 2^31, which covers a metre-to-sub-millimetre scene.
    /// @throw std::invalid_argument when @p buckets < 1, @p octavesPerBucket < 1 or
    ///        @p largestArea is not finite and positive.
    static std::vector<float> fixedLog2Boundaries(int buckets = 32, float largestArea = 1.0f,
                                                  int octavesPerBucket = 1);

private:
    std::vector<uint64_t> bins_;
    uint64_t count_ = 0;
    float min_ = 0.0f;
    float max_ = 0.0f;
};

/// @brief Reads @p source to its end into a histogram, then rewinds it: the stand-alone pre-pass
/// for bakes that have no rasterization pass to piggyback on.
/// @throw InputError from the source.
AreaHistogram histogramOf(TriangleSource& source);

}  // namespace penumbra
