#include "bucket/BucketPlan.h"

#include "stream/util/Progress.h"

#include <tbb/parallel_pipeline.h>

#include <array>
#include <vector>

namespace penumbra {
namespace {

/// Chunks in flight in the bucket pass: one read, one filtered and one written at a time. Each
/// holds a chunk, what the filter kept of it and their buckets (4 bytes a triangle, a tenth of
/// its 40): under seven chunk buffers, within the eight the memory plan counts for the replay's
/// read-ahead (BakeMemory.cpp), which starts only after the pass.
constexpr size_t kChunksInFlight = 3;

/// One chunk of the bucket pass, as it moves from the read through the filter to the writer.
struct PassChunk {
    std::vector<Triangle> read, kept;
    std::vector<uint32_t> buckets;  ///< of the triangles written: kept (with a filter) or read
    size_t count = 0;
};

/// The triangles of @p c that go to the buckets: those the filter kept, or all read.
std::span<const Triangle> written(const PassChunk& c, bool filtered) {
    return filtered ? std::span<const Triangle>(c.kept) : std::span<const Triangle>(c.read.data(), c.count);
}

}  // namespace

BucketRanges planBucketRanges(const BucketOptions& options, const AreaHistogram* histogram, float largestAreaHint) {
    options.validate();
    if (histogram && histogram->count() > 0) return BucketRanges(histogram->bucketBoundaries(options.buckets));
    return BucketRanges(AreaHistogram::fixedLog2Boundaries(options.buckets, largestAreaHint));
}

BucketSet writeBuckets(TriangleSource& source, const BucketRanges& ranges, const BucketOptions& options,
                       BucketStats* stats, const std::function<void(std::span<const Triangle>)>& onChunk,
                       const std::function<bool(const Triangle&)>& keep) {
    Stopwatch total;
    double writeSeconds = 0;
    uint64_t culled = 0;
    BucketWriter writer(ranges, options, source.sizeHint());
    // Three stages, so that with two threads the reach cull of one chunk overlaps the writes of
    // the one before and the read of the next (one after the other, the filter was a third of
    // the pass and the writes two fifths). The read and the writes stay serial and in stream
    // order, so the files are the same on any thread count.
    std::array<PassChunk, kChunksInFlight> chunks;
    size_t next = 0;
    tbb::parallel_pipeline(
        kChunksInFlight,
        tbb::make_filter<void, PassChunk*>(tbb::filter_mode::serial_in_order,
                                           [&](tbb::flow_control& flow) -> PassChunk* {
                                               // Slot reuse is safe: chunks leave the last (serial,
                                               // in-order) stage oldest first.
                                               PassChunk& c = chunks[next++ % kChunksInFlight];
                                               c.read.resize(kTriangleChunk);
                                               c.count = source.read(c.read);
                                               if (c.count == 0) {
                                                   flow.stop();
                                                   return nullptr;
                                               }
                                               if (onChunk) onChunk(std::span<const Triangle>(c.read.data(), c.count));
                                               return &c;
                                           }) &
            tbb::make_filter<PassChunk*, PassChunk*>(tbb::filter_mode::parallel,
                                                     [&](PassChunk* c) {
                                                         // The filter, and each kept triangle's
                                                         // bucket (its area and a search of the
                                                         // ranges), leave the serial writes only
                                                         // the copies and the write(2) calls.
                                                         if (keep) {
                                                             c->kept.clear();
                                                             for (size_t i = 0; i < c->count; ++i)
                                                                 if (keep(c->read[i])) c->kept.push_back(c->read[i]);
                                                         }
                                                         const std::span<const Triangle> got = written(*c, keep != nullptr);
                                                         c->buckets.resize(got.size());
                                                         for (size_t i = 0; i < got.size(); ++i) c->buckets[i] = writer.bucketOf(got[i]);
                                                         return c;
                                                     }) &
            tbb::make_filter<PassChunk*, void>(tbb::filter_mode::serial_in_order, [&](PassChunk* c) {
                const std::span<const Triangle> got = written(*c, keep != nullptr);
                culled += c->count - got.size();
                ScopedTimer timer(writeSeconds);
                writer.write(got, c->buckets);
            }));
    BucketSet set = [&] {
        ScopedTimer timer(writeSeconds);
        return writer.finish();
    }();
    if (stats) {
        *stats = BucketStats{};
        stats->triangles = set.triangles();
        stats->opaqueTriangles = set.opaqueTriangles();
        stats->alphaMatteTriangles = set.alphaMatteTriangles();
        stats->bytesWritten = set.bytes();
        stats->culledTriangles = culled;
        stats->ranges = set.ranges().count();
        for (const BucketInfo& b : set.buckets()) stats->nonEmptyFiles += b.triangles > 0;
        stats->writeSeconds = writeSeconds;
        stats->seconds = total.seconds();
    }
    return set;
}

}  // namespace penumbra
