#include "bucket/AreaHistogram.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace penumbra {

AreaHistogram::AreaHistogram() : bins_(kBinCount, 0) {}

size_t AreaHistogram::binOf(float sanitizedArea) {
    // For non-negative floats the bit pattern is monotone in the value, so dropping the low
    // mantissa bits is a monotone quantization with 2^6 steps per power of two.
    return static_cast<size_t>(std::bit_cast<uint32_t>(sanitizedArea) >> kShift);
}

float AreaHistogram::binLowerEdge(size_t bin) {
    return std::bit_cast<float>(static_cast<uint32_t>(bin << kShift));
}

void AreaHistogram::merge(const AreaHistogram& other) {
    if (other.count_ == 0) return;
    for (size_t i = 0; i < kBinCount; ++i) bins_[i] += other.bins_[i];
    min_ = count_ ? std::min(min_, other.min_) : other.min_;
    max_ = count_ ? std::max(max_, other.max_) : other.max_;
    count_ += other.count_;
}

std::vector<float> AreaHistogram::bucketBoundaries(int buckets) const {
    if (buckets < 1) throw std::invalid_argument("AreaHistogram::bucketBoundaries: buckets must be >= 1");

    // Candidate split points: the lower edge of every non-empty bin but the first, each with the
    // number of areas below it. Edges inside a run of empty bins are all equivalent; the one at
    // the next non-empty bin is the tightest, so only those are candidates. `below` strictly
    // increases along the list, which makes the nearest-to-target search a binary search.
    struct Candidate {
        float edge;
        uint64_t below;
    };
    std::vector<Candidate> candidates;
    uint64_t cumulative = 0;
    for (size_t bin = 0; bin < kBinCount; ++bin) {
        if (bins_[bin] == 0) continue;
        float edge = binLowerEdge(bin);
        // An infinite area (only from overflowing coordinates) stays in the top bucket with the
        // largest finite ones: BucketRanges accepts finite split points only.
        if (cumulative > 0 && edge != std::numeric_limits<float>::infinity()) candidates.push_back({edge, cumulative});
        cumulative += bins_[bin];
    }

    // Greedy from the smallest areas up: each split aims at an equal share of what is left for
    // the buckets that are left. Re-aiming after every split means a bin too big to cut (a
    // terrain of equal cells, instanced foliage) costs one oversized bucket, not a run of
    // merged splits: the rest of the distribution still gets all the remaining buckets.
    std::vector<float> splits;
    uint64_t start = 0;  // areas below the last split
    auto next = candidates.begin();
    for (int left = buckets; left > 1 && next != candidates.end(); --left) {
        const double target = static_cast<double>(start) + static_cast<double>(count_ - start) / left;
        auto it = std::lower_bound(next, candidates.end(), target,
                                   [](const Candidate& c, double t) { return static_cast<double>(c.below) < t; });
        // `it` is the first candidate at or above the target; its predecessor may be nearer,
        // as long as it is above the last split.
        if (it == candidates.end() ||
            (it != next && target - static_cast<double>(std::prev(it)->below) <
                               static_cast<double>(it->below) - target))
            --it;
        splits.push_back(it->edge);
        start = it->below;
        next = std::next(it);
    }
    return splits;
}

std::vector<float> AreaHistogram::fixedLog2Boundaries(int buckets, float largestArea, int octavesPerBucket) {
    if (buckets < 1) throw std::invalid_argument("AreaHistogram::fixedLog2Boundaries: buckets must be >= 1");
    if (octavesPerBucket < 1)
        throw std::invalid_argument("AreaHistogram::fixedLog2Boundaries: octavesPerBucket must be >= 1");
    if (!(largestArea > 0.0f) || !std::isfinite(largestArea))
        throw std::invalid_argument("AreaHistogram::fixedLog2Boundaries: largestArea must be finite and positive");

    // Exponent of the largest power of two <= largestArea, kept inside the normal range so
    // every split is an exact, positive, finite float.
    int exponent = std::ilogb(largestArea);
    exponent = std::clamp(exponent, std::numeric_limits<float>::min_exponent - 1,
                          std::numeric_limits<float>::max_exponent - 1);
    std::vector<float> splits;
    for (int k = 0; k < buckets - 1; ++k) {
        int64_t e = int64_t{exponent} - int64_t{k} * octavesPerBucket;
        if (e < std::numeric_limits<float>::min_exponent - 1) break;
        splits.push_back(std::ldexp(1.0f, static_cast<int>(e)));
    }
    std::reverse(splits.begin(), splits.end());
    return splits;
}

AreaHistogram histogramOf(TriangleSource& source) {
    AreaHistogram histogram;
    std::vector<Triangle> chunk(kTriangleChunk);
    while (size_t n = source.read(chunk)) histogram.add(std::span<const Triangle>(chunk.data(), n));
    source.rewind();
    return histogram;
}

}  // namespace penumbra
