#pragma once
/// @file BucketRanges.h
/// @brief The area ranges of the coarse blocker sort: which bucket a triangle of a given area
/// belongs to (Laine & Aila 2005, Section 3.3).
///
/// Ranges are described by their split points, ascending, as AreaHistogram produces them.
/// Buckets are numbered in replay order: bucket 0 holds the largest areas, bucket count()-1
/// the smallest. With split points b[0] < b[1] < ... < b[n-1] there are n + 1 buckets:
///
///     bucket 0        [b[n-1], +inf]
///     bucket k        [b[n-1-k], b[n-k])
///     bucket n        [0, b[0])
///
/// so every area of bucket i is >= every area of bucket i + 1. An area that is NaN, negative or
/// -0 (only a broken triangle has one) counts as 0 and lands in the smallest bucket: it is
/// replayed last, where it can do the least harm to the sort.

#include <algorithm>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace penumbra {

/// @brief A half-open area interval [lower, upper); upper is +inf for the largest bucket.
struct AreaRange {
    float lower = 0.0f;
    float upper = std::numeric_limits<float>::infinity();
    /// True when @p area (sanitized, see sanitizeArea()) falls in this range.
    bool contains(float area) const;
};

/// @brief Maps NaN, negative areas and -0 to +0, leaves everything else alone.
inline float sanitizeArea(float area) { return area > 0.0f ? area : 0.0f; }

inline bool AreaRange::contains(float area) const {
    float a = sanitizeArea(area);
    // +inf belongs to the top range, whose upper bound is itself +inf.
    return a >= lower && (a < upper || (a == upper && upper == std::numeric_limits<float>::infinity()));
}

/// @brief Split points plus the area -> bucket mapping. Cheap to copy (one small vector).
class BucketRanges {
public:
    /// @brief One bucket holding every area.
    BucketRanges() = default;

    /// @param ascendingSplits split points, strictly increasing, finite and > 0.
    /// @throw std::invalid_argument on anything else (a programming error, not user input).
    explicit BucketRanges(std::vector<float> ascendingSplits) : splits_(std::move(ascendingSplits)) {
        for (size_t i = 0; i < splits_.size(); ++i) {
            float s = splits_[i];
            if (!(s > 0.0f) || s == std::numeric_limits<float>::infinity())
                throw std::invalid_argument("BucketRanges: split " + std::to_string(i) + " is not finite and positive");
            if (i > 0 && !(splits_[i - 1] < s))
                throw std::invalid_argument("BucketRanges: splits are not strictly increasing at " + std::to_string(i));
        }
    }

    /// Number of buckets (split points + 1).
    size_t count() const { return splits_.size() + 1; }

    /// The split points, ascending, as given to the constructor.
    const std::vector<float>& splits() const { return splits_; }

    /// @brief The bucket of @p area, 0 for the largest areas.
    size_t bucketOf(float area) const {
        float a = sanitizeArea(area);
        // upper_bound counts the splits <= a, i.e. how many ranges lie entirely below a.
        size_t below = static_cast<size_t>(std::upper_bound(splits_.begin(), splits_.end(), a) - splits_.begin());
        return splits_.size() - below;
    }

    /// @brief The area range of bucket @p index (0 = largest).
    AreaRange range(size_t index) const {
        const size_t n = splits_.size();
        AreaRange r;
        if (index < n) r.lower = splits_[n - 1 - index];
        if (index > 0 && index <= n) r.upper = splits_[n - index];
        return r;
    }

private:
    std::vector<float> splits_;
};

}  // namespace penumbra
