// Tests for AreaHistogram (log2-binned area counts, quantile and fixed log2 split points) and
// BucketRanges (area -> bucket mapping, largest first).

#include "bucket/AreaHistogram.h"
#include "bucket/BucketRanges.h"
#include "stream/util/Random.h"
#include "stream/TriangleSource.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

using namespace penumbra;

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

/// Standard normal deviate from two uniforms (Box-Muller); deterministic given the Rng.
double gaussian(Rng& rng) {
    double u = std::max(rng.uniform(), 1e-300);
    return std::sqrt(-2.0 * std::log(u)) * std::cos(6.283185307179586 * rng.uniform());
}

/// Areas of a few skewed shapes a real scene has: log-normal (natural mesh detail), Pareto
/// (many small, few huge: terrain plus buildings), and 90% tiny foliage + 10% large walls.
std::vector<float> skewedAreas(int shape, int n, uint64_t seed) {
    Rng rng(seed);
    std::vector<float> a(n);
    for (int i = 0; i < n; ++i) {
        switch (shape) {
            case 0: a[i] = float(std::exp(-6.0 + 3.0 * gaussian(rng))); break;
            case 1: a[i] = float(1e-4 * std::pow(1.0 - rng.uniform(), -1.0 / 0.7)); break;
            default:
                a[i] = rng.uniform() < 0.9 ? float(1e-5 * (1.0 + rng.uniform())) : float(10.0 * (1.0 + 30.0 * rng.uniform()));
        }
    }
    return a;
}

/// Count per bucket (replay order) of @p areas under @p ranges.
std::vector<uint64_t> countPerBucket(const BucketRanges& ranges, const std::vector<float>& areas) {
    std::vector<uint64_t> counts(ranges.count(), 0);
    for (float a : areas) ++counts[ranges.bucketOf(a)];
    return counts;
}

}  // namespace

TEST_CASE("AreaHistogram bins are monotone, 64 per octave, with exact float edges", "[bucket]") {
    Rng rng(7);
    for (int i = 0; i < 10000; ++i) {
        float a = float(std::ldexp(1.0 + rng.uniform(), int(rng.uniform(-140, 120))));
        size_t bin = AreaHistogram::binOf(a);
        CHECK(AreaHistogram::binLowerEdge(bin) <= a);
        CHECK(a < AreaHistogram::binLowerEdge(bin + 1));
        if (std::isnormal(a) && std::isnormal(2 * a)) CHECK(AreaHistogram::binOf(2 * a) - bin == AreaHistogram::kBinsPerOctave);
    }
    CHECK(AreaHistogram::binOf(0.0f) == 0);
    CHECK(AreaHistogram::binOf(kInf) < AreaHistogram::kBinCount);
    CHECK(AreaHistogram::binLowerEdge(AreaHistogram::binOf(1.0f)) == 1.0f);
    // Consecutive edges never shrink.
    for (size_t b = 1; b < AreaHistogram::binOf(kInf); ++b)
        REQUIRE(AreaHistogram::binLowerEdge(b - 1) < AreaHistogram::binLowerEdge(b));
}

TEST_CASE("AreaHistogram counts areas, min, max and treats broken areas as zero", "[bucket]") {
    AreaHistogram h;
    CHECK(h.count() == 0);
    CHECK(h.minArea() == 0.0f);
    CHECK(h.maxArea() == 0.0f);
    CHECK(h.bucketBoundaries(32).empty());

    h.add(2.0f);
    h.add(0.5f);
    h.add(std::numeric_limits<float>::quiet_NaN());
    h.add(-0.0f);
    Triangle t{{glm::vec3(0, 0, 0), glm::vec3(2, 0, 0), glm::vec3(0, 3, 0)}, 0};
    h.add(t);  // area 3
    CHECK(h.count() == 5);
    CHECK(h.minArea() == 0.0f);
    CHECK(h.maxArea() == 3.0f);
    CHECK(h.binCount(0) == 2);
    CHECK(h.binCount(AreaHistogram::binOf(3.0f)) == 1);

    AreaHistogram other;
    other.add(100.0f);
    h.merge(other);
    h.merge(AreaHistogram{});
    CHECK(h.count() == 6);
    CHECK(h.maxArea() == 100.0f);
    AreaHistogram empty;
    empty.merge(other);
    CHECK(empty.minArea() == 100.0f);
}

TEST_CASE("Quantile boundaries are monotone and balance skewed distributions", "[bucket]") {
    const int n = 200000;
    for (int shape = 0; shape < 3; ++shape) {
        for (int buckets : {1, 2, 7, 32, 100}) {
            CAPTURE(shape, buckets);
            std::vector<float> areas = skewedAreas(shape, n, 42 + shape);
            AreaHistogram h;
            for (float a : areas) h.add(a);
            std::vector<float> splits = h.bucketBoundaries(buckets);
            REQUIRE(splits.size() <= size_t(buckets - 1));
            for (size_t i = 0; i < splits.size(); ++i) {
                CHECK(splits[i] > 0.0f);
                CHECK(std::isfinite(splits[i]));
                if (i) CHECK(splits[i - 1] < splits[i]);
            }
            BucketRanges ranges(splits);  // would throw on a non-monotone list
            std::vector<uint64_t> counts = countPerBucket(ranges, areas);
            // No bucket is ever empty: a split is only placed between areas that exist.
            for (uint64_t c : counts) CHECK(c > 0);
            // The largest bin decides how well a split can hit its target: it cannot cut a bin.
            uint64_t largestBin = 0;
            for (size_t b = 0; b < AreaHistogram::kBinCount; ++b) largestBin = std::max(largestBin, h.binCount(b));
            uint64_t total = 0;
            for (uint64_t c : counts) total += c;
            CHECK(total == uint64_t(n));
            // A split cannot cut a bin, so each one misses its target by at most half the bin it
            // falls in, and a bucket (between two splits) by about the largest bin. When no bin
            // holds a whole share there are always enough bin edges for every split.
            const double share = double(n) / buckets;
            if (double(largestBin) < share) {
                REQUIRE(splits.size() == size_t(buckets - 1));
                for (uint64_t c : counts) CHECK(std::abs(double(c) - share) <= std::max(0.10 * share, double(largestBin)));
            }
            if (shape == 0 && buckets <= 32) {
                // A smooth spread over many octaves at the default count: within 10% of an equal
                // share. (The Pareto shape has 38% of its areas in one octave, so its bins are
                // 1/3 of a share and it only meets the largest-bin bound above.)
                for (uint64_t c : counts) CHECK(std::abs(double(c) - share) <= 0.10 * share);
            }
        }
    }
}

TEST_CASE("Quantile split points classify exactly as the histogram counted", "[bucket]") {
    std::vector<float> areas = skewedAreas(0, 50000, 3);
    AreaHistogram h;
    for (float a : areas) h.add(a);
    BucketRanges ranges(h.bucketBoundaries(16));
    std::vector<uint64_t> counts = countPerBucket(ranges, areas);
    // Summing the histogram bins inside each range gives the same counts: splits sit on bin edges.
    std::vector<uint64_t> fromBins(ranges.count(), 0);
    for (size_t b = 0; b < AreaHistogram::kBinCount; ++b)
        if (h.binCount(b)) fromBins[ranges.bucketOf(AreaHistogram::binLowerEdge(b))] += h.binCount(b);
    CHECK(counts == fromBins);
}

TEST_CASE("Quantile boundaries degrade gracefully on degenerate distributions", "[bucket]") {
    SECTION("identical areas give one bucket") {
        AreaHistogram h;
        for (int i = 0; i < 1000; ++i) h.add(0.25f);
        CHECK(h.bucketBoundaries(32).empty());
    }
    SECTION("half identical, half spread: the big bin is not split, the rest stays balanced") {
        std::vector<float> areas(20000, 1.0f);
        Rng rng(5);
        for (int i = 0; i < 20000; ++i) areas.push_back(float(std::ldexp(1.0 + rng.uniform(), -int(rng.uniform(2, 22)))));
        AreaHistogram h;
        for (float a : areas) h.add(a);
        std::vector<float> splits = h.bucketBoundaries(32);
        BucketRanges ranges(splits);
        std::vector<uint64_t> counts = countPerBucket(ranges, areas);
        CHECK(counts[0] == 20000);  // the identical quads, in the top bucket together
        CHECK(ranges.count() >= 16);
        for (size_t k = 1; k < counts.size(); ++k) CHECK(counts[k] > 0);
    }
    SECTION("zero and infinite areas stay at the ends") {
        AreaHistogram h;
        for (int i = 0; i < 100; ++i) h.add(0.0f);
        for (int i = 0; i < 100; ++i) h.add(float(i + 1));
        for (int i = 0; i < 100; ++i) h.add(kInf);
        BucketRanges ranges(h.bucketBoundaries(3));
        CHECK(ranges.bucketOf(kInf) == 0);
        CHECK(ranges.bucketOf(0.0f) == ranges.count() - 1);
        for (float s : ranges.splits()) CHECK(std::isfinite(s));
    }
    CHECK_THROWS_AS(AreaHistogram().bucketBoundaries(0), std::invalid_argument);
}

TEST_CASE("Fixed log2 boundaries are powers of two below the reference area", "[bucket]") {
    std::vector<float> s = AreaHistogram::fixedLog2Boundaries(32, 3.0f);
    REQUIRE(s.size() == 31);
    CHECK(s.back() == 2.0f);  // largest power of two <= 3
    for (size_t i = 1; i < s.size(); ++i) CHECK(s[i] == 2.0f * s[i - 1]);
    CHECK(s.front() == std::ldexp(1.0f, 1 - 30));

    std::vector<float> two = AreaHistogram::fixedLog2Boundaries(4, 1.0f, 2);
    CHECK(two == std::vector<float>{1.0f / 16, 1.0f / 4, 1.0f});

    CHECK(AreaHistogram::fixedLog2Boundaries(1, 1.0f).empty());
    // Clamped to normal floats: never a zero or denormal split, never an infinite one.
    std::vector<float> tiny = AreaHistogram::fixedLog2Boundaries(64, 1e-36f, 1);
    CHECK(tiny.front() == std::numeric_limits<float>::min());
    CHECK(tiny.size() < 63);
    std::vector<float> huge = AreaHistogram::fixedLog2Boundaries(8, std::numeric_limits<float>::max(), 1000000000);
    CHECK(huge == std::vector<float>{std::ldexp(1.0f, 127)});
    BucketRanges ok(tiny);

    CHECK_THROWS_AS(AreaHistogram::fixedLog2Boundaries(0, 1.0f), std::invalid_argument);
    CHECK_THROWS_AS(AreaHistogram::fixedLog2Boundaries(4, 0.0f), std::invalid_argument);
    CHECK_THROWS_AS(AreaHistogram::fixedLog2Boundaries(4, kInf), std::invalid_argument);
    CHECK_THROWS_AS(AreaHistogram::fixedLog2Boundaries(4, 1.0f, 0), std::invalid_argument);
}

TEST_CASE("BucketRanges maps areas to buckets largest first", "[bucket]") {
    BucketRanges ranges({1.0f, 4.0f, 16.0f});
    REQUIRE(ranges.count() == 4);
    CHECK(ranges.bucketOf(100.0f) == 0);
    CHECK(ranges.bucketOf(16.0f) == 0);
    CHECK(ranges.bucketOf(15.9f) == 1);
    CHECK(ranges.bucketOf(4.0f) == 1);
    CHECK(ranges.bucketOf(1.0f) == 2);
    CHECK(ranges.bucketOf(0.5f) == 3);
    CHECK(ranges.bucketOf(0.0f) == 3);
    CHECK(ranges.bucketOf(std::numeric_limits<float>::quiet_NaN()) == 3);
    CHECK(ranges.bucketOf(-1.0f) == 3);
    CHECK(ranges.bucketOf(kInf) == 0);

    CHECK(ranges.range(0).lower == 16.0f);
    CHECK(ranges.range(0).upper == kInf);
    CHECK(ranges.range(1).lower == 4.0f);
    CHECK(ranges.range(1).upper == 16.0f);
    CHECK(ranges.range(3).lower == 0.0f);
    CHECK(ranges.range(3).upper == 1.0f);
    for (size_t k = 0; k + 1 < ranges.count(); ++k) CHECK(ranges.range(k).lower == ranges.range(k + 1).upper);

    Rng rng(11);
    for (int i = 0; i < 1000; ++i) {
        float a = float(std::ldexp(rng.uniform(), int(rng.uniform(-10, 10))));
        CHECK(ranges.range(ranges.bucketOf(a)).contains(a));
    }
    CHECK(ranges.range(0).contains(kInf));

    BucketRanges one;
    CHECK(one.count() == 1);
    CHECK(one.bucketOf(123.0f) == 0);

    CHECK_THROWS_AS(BucketRanges({2.0f, 1.0f}), std::invalid_argument);
    CHECK_THROWS_AS(BucketRanges({1.0f, 1.0f}), std::invalid_argument);
    CHECK_THROWS_AS(BucketRanges({0.0f}), std::invalid_argument);
    CHECK_THROWS_AS(BucketRanges({kInf}), std::invalid_argument);
    CHECK_THROWS_AS(BucketRanges({std::numeric_limits<float>::quiet_NaN()}), std::invalid_argument);
}

TEST_CASE("histogramOf reads a source once and rewinds it", "[bucket]") {
    std::vector<Triangle> tris;
    for (int i = 1; i <= 10000; ++i) tris.push_back({{glm::vec3(0), glm::vec3(float(i), 0, 0), glm::vec3(0, 2, 0)}, 0});
    VectorSource source(tris);
    AreaHistogram h = histogramOf(source);
    CHECK(h.count() == 10000);
    CHECK(h.minArea() == 1.0f);
    CHECK(h.maxArea() == 10000.0f);
    CHECK(readAll(source).size() == 10000);  // rewound
}
