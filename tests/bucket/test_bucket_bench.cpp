// Throughput of the bucket stage on a realistic scene: not a test (hidden, never in CI), the
// source of the numbers in docs/buckets.md. Run:
//
//     ./build/penumbra_tests "[bucket-bench]"
//
// Environment: PENUMBRA_BUCKET_BENCH_TREES (forest size, default 1000, ~2.7M triangles),
// PENUMBRA_BUCKET_BENCH_BLADES (grass blades, default 400000, 2M triangles), always with a
// 1000x1000-cell terrain of 2M triangles; PENUMBRA_BUCKET_BENCH_TMP (bucket directory parent, default
// the system temp dir), PENUMBRA_BUCKET_BENCH_KEEP=1 (keep the buckets, e.g. to try compressors
// on them), PENUMBRA_BUCKET_BENCH_BUFFER (write buffer bytes per bucket).

#include "bucket/AreaHistogram.h"
#include "bucket/BucketPlan.h"
#include "procedural/Generators.h"
#include "stream/util/Memory.h"
#include "stream/util/Progress.h"
#include "stream/SourceRegistry.h"

#include <catch2/catch.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <vector>

using namespace penumbra;

namespace {

/// Terrain (2M equal-ish cells), grass (blades of 5 triangles, every one different) and a
/// forest (8 instanced tree variants, alpha-matte leaves): the three kinds of geometry the
/// procedural scenes are made of, with very different area distributions and redundancy.
TriangleSourcePtr benchScene(int trees, int blades) {
    registerProceduralGenerators();
    static const nlohmann::json terrain = {{"area", {{-50, -50}, {50, 50}}}, {"resolution", 1000}, {"amplitude", 3.0}};
    static nlohmann::json forest, grass;
    forest = {{"count", trees}, {"terrain", terrain}};
    grass = {{"count", blades}, {"terrain", terrain}};
    std::vector<TriangleSourcePtr> parts;
    parts.push_back(openSource("terrain", SourceRequest{terrain, "bench", "terrain", "."}));
    if (blades > 0) parts.push_back(openSource("grass", SourceRequest{grass, "bench", "grass", "."}));
    if (trees > 0) parts.push_back(openSource("forest", SourceRequest{forest, "bench", "forest", "."}));
    return std::make_unique<ConcatSource>(std::move(parts));
}

void report(const char* what, uint64_t triangles, uint64_t bytes, double seconds) {
    std::cout << fmt::format("{:<44} {:>7.3f} s  {:>7.1f} Mtri/s  {:>8.1f} MB/s\n", what, seconds,
                             triangles / seconds / 1e6, bytes / seconds / 1e6);
}

/// Smallest and largest opaque bucket, to compare how evenly two range choices fill buckets.
std::string occupancy(const BucketSet& set) {
    uint64_t lo = UINT64_MAX, hi = 0;
    size_t used = 0;
    for (const BucketInfo& b : set.buckets())
        if (!b.alphaMatte) {
            if (b.triangles) ++used;
            lo = std::min(lo, b.triangles);
            hi = std::max(hi, b.triangles);
        }
    return fmt::format("{} of {} opaque buckets used, smallest {} largest {}", used, set.ranges().count(), lo, hi);
}

}  // namespace

TEST_CASE("Bucket throughput benchmark", "[.][bucket-bench]") {
    const char* treesEnv = std::getenv("PENUMBRA_BUCKET_BENCH_TREES");
    const int trees = treesEnv ? std::atoi(treesEnv) : 1000;
    const char* bladesEnv = std::getenv("PENUMBRA_BUCKET_BENCH_BLADES");
    const int blades = bladesEnv ? std::atoi(bladesEnv) : 400000;
    BucketOptions options;
    if (const char* tmp = std::getenv("PENUMBRA_BUCKET_BENCH_TMP")) options.tmpDir = tmp;
    options.keep = std::getenv("PENUMBRA_BUCKET_BENCH_KEEP") != nullptr;
    if (const char* buffer = std::getenv("PENUMBRA_BUCKET_BENCH_BUFFER")) options.writeBufferBytes = std::atol(buffer);

    TriangleSourcePtr source = benchScene(trees, blades);
    const uint64_t n = source->sizeHint().value_or(0);
    std::cout << fmt::format("scene: terrain + {} grass blades + {} trees, {} triangles ({:.0f} MB raw)\n", blades, trees,
                             n, n * 40 / 1e6);

    // 1. What the source costs alone, so the bucket pass can be read against it.
    Stopwatch clock;
    std::vector<Triangle> chunk(kTriangleChunk);
    uint64_t got = 0;
    while (size_t k = source->read(chunk)) got += k;
    report("generate only (procedural source)", got, got * 40, clock.seconds());
    source->rewind();

    // 2. Histogram pre-pass over the source (what a camera-receiver pass adds when it feeds add()).
    clock.reset();
    AreaHistogram histogram = histogramOf(*source);
    report("generate + histogram", histogram.count(), got * 40, clock.seconds());
    if (n <= 20000000) {  // the in-memory comparison needs the whole scene in RAM
        std::vector<Triangle> all = readAll(*source);
        source->rewind();
        clock.reset();
        AreaHistogram h2;
        h2.add(all);
        report("histogram.add() alone (in memory)", all.size(), all.size() * 40, clock.seconds());

        // 3. Bucket pass from memory: the bucket stage's own cost, no generator in the way.
        VectorSource memory(std::move(all));
        BucketStats stats;
        BucketSet set = writeBuckets(memory, planBucketRanges(options, &histogram), options, &stats);
        report("write buckets from memory (quantile ranges)", stats.triangles, stats.bytesWritten, stats.seconds);
        std::cout << "  " << occupancy(set) << "\n";
        memory.rewind();
        BucketSet fixed = writeBuckets(memory, planBucketRanges(options, nullptr), options);
        std::cout << "  fixed log2 ranges below 1: " << occupancy(fixed) << "\n";
    }

    // 4. The real pass: source -> buckets, then replays.
    BucketStats stats;
    const uint64_t rssBefore = peakRssBytes();
    auto set = std::make_shared<BucketSet>(writeBuckets(*source, planBucketRanges(options, &histogram), options, &stats));
    report("generate + write buckets", stats.triangles, stats.bytesWritten, stats.seconds);
    std::cout << fmt::format("  {:.1f} bytes/triangle, {} written, writer time {:.3f} s, peak RSS {} -> {}\n",
                             stats.bytesPerTriangle(), formatBytes(stats.bytesWritten), stats.writeSeconds,
                             formatBytes(rssBefore), formatBytes(peakRssBytes()));
    BucketReplaySource replay(set, options.readBufferBytes);
    for (int pass = 0; pass < 2; ++pass) {
        clock.reset();
        uint64_t k = 0;
        while (size_t m = replay.read(chunk)) k += m;
        report(pass == 0 ? "replay pass 1" : "replay pass 2 (after rewind)", k, k * 40, clock.seconds());
        replay.rewind();
    }
    std::cout << fmt::format("  bytes read {} over {} passes, pread time {:.3f} s\n", formatBytes(replay.bytesRead()),
                             replay.passes() - 1, replay.readSeconds());
    if (set->kept()) std::cout << "kept in " << set->directory() << "\n";
}
