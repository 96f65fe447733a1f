#include "bucket/BucketPlan.h"

#include "stream/Progress.h"

#include <vector>

namespace penumbra {

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
    std::vector<Triangle> chunk(kTriangleChunk), kept;
    if (keep) kept.reserve(kTriangleChunk);
    while (size_t n = source.read(chunk)) {
        std::span<const Triangle> got(chunk.data(), n);
        if (onChunk) onChunk(got);
        if (keep) {
            kept.clear();
            for (const Triangle& t : got)
                if (keep(t)) kept.push_back(t);
            culled += got.size() - kept.size();
            got = kept;
        }
        ScopedTimer timer(writeSeconds);
        writer.write(got);
    }
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
