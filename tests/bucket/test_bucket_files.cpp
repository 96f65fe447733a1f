// Tests for the out-of-core bucket stage: BucketWriter, BucketSet, BucketReplaySource,
// writeBuckets/planBucketRanges.
//
// A file-size limit (standing in for a full disk) and death by SIGTERM cannot be staged in the
// test process itself, so those tests re-execute this binary on a hidden helper test case with
// the limit or the signal applied in the fresh process, and check the directory afterwards.

#include "bucket/AreaHistogram.h"
#include "bucket/BucketFiles.h"
#include "stream/PrefetchSource.h"
#include "bucket/BucketPlan.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/Memory.h"
#include "stream/util/Random.h"
#include "stream/TriangleSource.h"

#include "TestSupport.h"

#include <catch2/catch.hpp>
#include <tbb/global_control.h>

#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <iostream>
#include <string>
#include <vector>


namespace fs = std::filesystem;
using namespace penumbra::test;
using namespace penumbra;

namespace {

/// Triangle @p i of a deterministic stream: edge lengths over ~12 octaves (areas over ~24), every
/// 7th alpha-matte, and the index in the upper flag bits so identity and order can be checked.
Triangle makeTriangle(uint64_t seed, uint64_t i) {
    uint64_t h = hashIndex(seed, i);
    float edge = std::ldexp(1.0f + float(h & 0xffff) / 65536.0f, -int((h >> 16) % 12));
    glm::vec3 o(float((h >> 20) & 0xff), float((h >> 28) & 0xff), float((h >> 36) & 0xff));
    float stretch = 0.25f + float((h >> 44) & 0xff) / 64.0f;
    Triangle t{{o, o + glm::vec3(edge, 0, 0), o + glm::vec3(0, edge * stretch, 0.1f * edge)}, 0};
    t.flags = uint32_t(i << 1) | (i % 7 == 3 ? kTriangleAlphaMatte : 0u);
    return t;
}
uint64_t idOf(const Triangle& t) { return t.flags >> 1; }

/// Generates makeTriangle(seed, 0 .. count-1) on the fly, holding no triangles.
class GeneratedSource final : public TriangleSource {
public:
    GeneratedSource(uint64_t count, uint64_t seed = 1) : count_(count), seed_(seed) {}
    size_t read(std::span<Triangle> out) override {
        size_t n = size_t(std::min<uint64_t>(out.size(), count_ - next_));
        for (size_t k = 0; k < n; ++k) out[k] = makeTriangle(seed_, next_ + k);
        next_ += n;
        return n;
    }
    void rewind() override { next_ = 0; }
    std::string name() const override { return "generated"; }
    std::optional<uint64_t> sizeHint() const override { return count_; }

private:
    uint64_t count_, seed_, next_ = 0;
};

std::vector<Triangle> generate(uint64_t count, uint64_t seed = 1) {
    GeneratedSource s(count, seed);
    return readAll(s);
}

bool sameBytes(const Triangle& a, const Triangle& b) { return std::memcmp(&a, &b, sizeof(Triangle)) == 0; }

/// Replays @p source to its end in chunks of @p chunk triangles.
std::vector<Triangle> replayAll(TriangleSource& source, size_t chunk) {
    std::vector<Triangle> all, buf(chunk);
    while (size_t n = source.read(buf)) {
        REQUIRE(n <= chunk);
        all.insert(all.end(), buf.begin(), buf.begin() + n);
    }
    return all;
}

/// Writes @p tris into buckets and returns the set, shared for replays.
std::shared_ptr<const BucketSet> bucketize(const std::vector<Triangle>& tris, const BucketRanges& ranges,
                                           BucketOptions options) {
    BucketWriter writer(ranges, options, tris.size());
    // Uneven write sizes, so buffer boundaries fall everywhere.
    size_t i = 0, step = 1;
    while (i < tris.size()) {
        size_t n = std::min(step, tris.size() - i);
        writer.write(std::span<const Triangle>(tris.data() + i, n));
        i += n;
        step = step * 3 % 1001 + 1;
    }
    return std::make_shared<BucketSet>(writer.finish());
}

size_t openDescriptors() {
    size_t n = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator("/proc/self/fd")) ++n;
    return n;
}

// --- child processes ------------------------------------------------------------------------

const char* helperDir() { return std::getenv("PENUMBRA_BUCKET_HELPER_DIR"); }

/// Runs this binary on the hidden test case @p tag with PENUMBRA_BUCKET_HELPER_DIR=@p dir and,
/// if @p fileSizeLimit > 0, that RLIMIT_FSIZE with SIGXFSZ ignored (so an oversize write fails
/// with EFBIG, exactly as under `prlimit --fsize`). Returns the wait status; output in @p output.
int runHelper(const std::string& tag, const std::string& dir, rlim_t fileSizeLimit, std::string& output) {
    return runSelfAsChild(tag, "PENUMBRA_BUCKET_HELPER_DIR", dir, fileSizeLimit, output);
}

}  // namespace

// --- replay order and content ---------------------------------------------------------------

TEST_CASE("Bucket replay yields every triangle once, largest ranges first, opaque before alpha", "[bucket]") {
    ScratchDir dir;
    const std::vector<Triangle> input = generate(30000, 9);
    AreaHistogram h;
    h.add(input);
    BucketOptions options;
    options.tmpDir = dir.path.string();
    options.writeBufferBytes = 4000;  // 100 records: many flushes per bucket
    const int buckets = GENERATE(1, 5, 32);
    CAPTURE(buckets);
    BucketRanges ranges(h.bucketBoundaries(buckets));
    auto set = bucketize(input, ranges, options);
    const size_t B = ranges.count();

    REQUIRE(set->buckets().size() == 2 * B);
    CHECK(set->triangles() == input.size());
    CHECK(set->bytes() == input.size() * sizeof(Triangle));
    uint64_t alpha = 0;
    for (const Triangle& t : input) alpha += (t.flags & kTriangleAlphaMatte) != 0;
    CHECK(set->alphaMatteTriangles() == alpha);
    CHECK(set->opaqueTriangles() == input.size() - alpha);

    // Ranges: bucket i lies entirely at or above bucket i + 1, within each kind.
    for (size_t i = 0; i < 2 * B; ++i) {
        const BucketInfo& b = set->buckets()[i];
        CHECK(b.alphaMatte == (i >= B));
        CHECK(b.range == i % B);
        CHECK(b.path.empty());
        if (i % B + 1 < B) CHECK(b.areas.lower >= set->buckets()[i + 1].areas.upper);
    }

    BucketReplaySource replay(set, 1 << 16);
    CHECK(replay.sizeHint() == input.size());
    // The progress estimate's runs: the opaque triangles, then the alpha-matte ones, as replayed.
    CHECK(replay.costRuns() == std::vector<uint64_t>{input.size() - alpha, alpha});
    CHECK(PrefetchSource(std::make_unique<BucketReplaySource>(set, 1 << 16)).costRuns() == replay.costRuns());
    std::vector<Triangle> out = replayAll(replay, kTriangleChunk);
    REQUIRE(out.size() == input.size());

    // Same multiset: every id exactly once, with identical bytes.
    std::vector<char> seen(input.size(), 0);
    for (const Triangle& t : out) {
        uint64_t id = idOf(t);
        REQUIRE(id < input.size());
        CHECK(seen[id] == 0);
        seen[id] = 1;
        CHECK(sameBytes(t, input[id]));
    }

    // Order: the replay index (alpha * B + range) never decreases, each triangle sits in its
    // bucket's range, and within a bucket ids increase (stream order).
    std::vector<uint64_t> perBucket(2 * B, 0);
    std::vector<float> minArea(2 * B, INFINITY), maxArea(2 * B, 0.0f);
    size_t previous = 0;
    uint64_t previousId = 0;
    for (size_t k = 0; k < out.size(); ++k) {
        const Triangle& t = out[k];
        const bool isAlpha = (t.flags & kTriangleAlphaMatte) != 0;
        const size_t index = (isAlpha ? B : 0) + ranges.bucketOf(t.area());
        REQUIRE(index >= previous);
        if (k > 0 && index == previous) REQUIRE(idOf(t) > previousId);
        CHECK(set->buckets()[index].areas.contains(t.area()));
        ++perBucket[index];
        minArea[index] = std::min(minArea[index], t.area());
        maxArea[index] = std::max(maxArea[index], t.area());
        previous = index;
        previousId = idOf(t);
    }
    for (size_t i = 0; i < 2 * B; ++i) {
        CHECK(perBucket[i] == set->buckets()[i].triangles);
        CHECK(set->buckets()[i].bytes == perBucket[i] * sizeof(Triangle));
        // Actual areas, not just ranges: all of bucket i >= all of the next non-empty bucket.
        for (size_t j = i + 1; j < 2 * B && j / B == i / B; ++j)
            if (perBucket[i] && perBucket[j]) CHECK(minArea[i] >= maxArea[j]);
    }
    CHECK(replay.currentBucket() == 2 * B);
    CHECK(replay.bytesRead() == set->bytes());
}

TEST_CASE("Bucket replay is identical across rewinds, chunk sizes and buffer sizes", "[bucket]") {
    ScratchDir dir;
    const std::vector<Triangle> input = generate(20000, 4);
    BucketOptions options;
    options.tmpDir = dir.path.string();
    options.writeBufferBytes = GENERATE(40, 1000, 64 * 1024);
    CAPTURE(options.writeBufferBytes);
    auto set = bucketize(input, BucketRanges(AreaHistogram::fixedLog2Boundaries(12, 16.0f)), options);

    BucketReplaySource first(set);
    const std::vector<Triangle> reference = replayAll(first, kTriangleChunk);
    REQUIRE(reference.size() == input.size());
    for (size_t readBuffer : {size_t(40), size_t(1000), size_t(64 * 1024)}) {
        BucketReplaySource replay(set, readBuffer);
        for (size_t chunk : {size_t(1), size_t(7), size_t(1000), size_t(5000), size_t(100000)}) {
            CAPTURE(readBuffer, chunk);
            std::vector<Triangle> again = replayAll(replay, chunk);
            REQUIRE(again.size() == reference.size());
            CHECK(std::equal(again.begin(), again.end(), reference.begin(), sameBytes));
            replay.rewind();
        }
        CHECK(replay.passes() == 6);
        CHECK(replay.bytesRead() == 5 * set->bytes());
    }

    SECTION("rewind in the middle of a bucket restarts from the first triangle") {
        BucketReplaySource replay(set);
        std::vector<Triangle> some(777);
        CHECK(replay.read(some) == 777);
        replay.rewind();
        std::vector<Triangle> again = replayAll(replay, 999);
        CHECK(std::equal(again.begin(), again.end(), reference.begin(), reference.end(), sameBytes));
    }
    SECTION("two replays of one set are independent") {
        BucketReplaySource a(set), b(set);
        std::vector<Triangle> ca(333), cb(500), outA, outB;
        for (;;) {
            size_t na = a.read(ca), nb = b.read(cb);
            outA.insert(outA.end(), ca.begin(), ca.begin() + na);
            outB.insert(outB.end(), cb.begin(), cb.begin() + nb);
            if (!na && !nb) break;
        }
        CHECK(std::equal(outA.begin(), outA.end(), reference.begin(), reference.end(), sameBytes));
        CHECK(std::equal(outB.begin(), outB.end(), reference.begin(), reference.end(), sameBytes));
    }
}

TEST_CASE("Buckets found ahead (the pass's parallel stage) write what write() alone writes", "[bucket]") {
    ScratchDir dir;
    std::vector<Triangle> input = generate(20000, 4);
    for (size_t i = 0; i < input.size(); i += 5) input[i].flags |= kTriangleAlphaMatte;  // the alpha buckets too
    BucketOptions options;
    options.tmpDir = dir.path.string();
    options.writeBufferBytes = GENERATE(40, 64 * 1024);
    const BucketRanges ranges(AreaHistogram::fixedLog2Boundaries(12, 16.0f));
    const auto reference = bucketize(input, ranges, options);

    BucketWriter writer(ranges, options);
    std::vector<uint32_t> buckets;
    for (const Triangle& t : input) buckets.push_back(writer.bucketOf(t));
    CHECK(*std::max_element(buckets.begin(), buckets.end()) >= ranges.count());  // an alpha bucket
    for (size_t first = 0; first < input.size(); first += 777) {
        const size_t n = std::min<size_t>(777, input.size() - first);
        writer.write(std::span<const Triangle>(input).subspan(first, n), std::span<const uint32_t>(buckets).subspan(first, n));
    }
    auto ahead = std::make_shared<BucketSet>(writer.finish());
    BucketReplaySource a(reference), b(ahead);
    const std::vector<Triangle> want = replayAll(a, kTriangleChunk), got = replayAll(b, kTriangleChunk);
    REQUIRE(got.size() == input.size());
    CHECK(std::equal(got.begin(), got.end(), want.begin(), want.end(), sameBytes));
    CHECK(ahead->bytes() == reference->bytes());
    CHECK(ahead->alphaMatteTriangles() == reference->alphaMatteTriangles());
}

TEST_CASE("An empty input gives an empty, replayable bucket set", "[bucket]") {
    ScratchDir dir;
    BucketOptions options;
    options.tmpDir = dir.path.string();
    auto set = bucketize({}, BucketRanges({1.0f}), options);
    CHECK(set->triangles() == 0);
    CHECK(set->bytes() == 0);
    BucketReplaySource replay(set);
    std::vector<Triangle> chunk(10);
    CHECK(replay.read(chunk) == 0);
    replay.rewind();
    CHECK(replay.read(chunk) == 0);
    CHECK(replay.read(std::span<Triangle>()) == 0);
}

// --- memory ---------------------------------------------------------------------------------

TEST_CASE("Writing 2M triangles keeps memory bounded by the bucket buffers", "[bucket]") {
    ScratchDir dir;
    BucketOptions options;
    options.tmpDir = dir.path.string();
    GeneratedSource source(2000000, 5);
    BucketRanges ranges(AreaHistogram::fixedLog2Boundaries(options.buckets, 1.0f));

    BucketWriter writer(ranges, options, source.sizeHint());
    std::vector<Triangle> chunk(kTriangleChunk);
    const uint64_t rssBefore = currentRssBytes();
    uint64_t rssMax = rssBefore, buffersMax = 0;
    while (size_t n = source.read(chunk)) {
        writer.write(std::span<const Triangle>(chunk.data(), n));
        buffersMax = std::max(buffersMax, writer.bufferBytes());
        rssMax = std::max(rssMax, currentRssBytes());
    }
    BucketSet set = writer.finish();
    CHECK(writer.bufferBytes() == 0);
    CHECK(set.triangles() == 2000000);
    CHECK(set.bytes() == 2000000 * sizeof(Triangle));
    // The structural bound: one buffer per bucket file, whatever the triangle count.
    CHECK(buffersMax <= options.writeMemoryBytes());
    CHECK(buffersMax > 0);
    // And what the process actually holds: the 80 MB written must not show up in RSS (page
    // cache is not resident set). 16 MiB covers the 4 MiB of buffers plus allocator slack.
    INFO("RSS before " << formatBytes(rssBefore) << ", max " << formatBytes(rssMax));
    CHECK(rssMax - rssBefore < 16u * 1024 * 1024);
}

// --- files, directories, keep ---------------------------------------------------------------

TEST_CASE("Unkept buckets leave no name on disk and release their files", "[bucket]") {
    // O_TMPFILE, and the create-and-unlink fallback of file systems without it.
    struct Fallback {
        explicit Fallback(bool on) : on(on) {
            if (on) ::setenv("PENUMBRA_NO_TMPFILE", "1", 1);
        }
        ~Fallback() {
            if (on) ::unsetenv("PENUMBRA_NO_TMPFILE");
        }
        bool on;
    } fallback(GENERATE(false, true));
    ScratchDir dir;
    BucketOptions options;
    options.tmpDir = dir.path.string();
    const size_t fdsBefore = openDescriptors();
    {
        BucketWriter writer(BucketRanges({0.01f, 0.1f}), options);
        CHECK(writer.directory().rfind((dir.path / "penumbra-buckets-").string(), 0) == 0);
        // Anonymous files: the directory is already gone while the writer is still open.
        CHECK(dir.find("").empty());
        std::vector<Triangle> tris = generate(10000);
        writer.write(tris);
        CHECK(dir.find("").empty());
        auto set = std::make_shared<BucketSet>(writer.finish());
        CHECK(!set->kept());
        CHECK(openDescriptors() == fdsBefore + 6);
        BucketReplaySource replay(set);
        CHECK(replayAll(replay, 4096).size() == 10000);
    }
    CHECK(openDescriptors() == fdsBefore);
    CHECK(dir.find("").empty());

    SECTION("an abandoned writer also releases everything") {
        {
            BucketWriter writer(BucketRanges({0.01f}), options);
            std::vector<Triangle> tris = generate(50000);
            writer.write(tris);
        }
        CHECK(openDescriptors() == fdsBefore);
        CHECK(dir.find("").empty());
    }
}

TEST_CASE("Kept buckets stay on disk as raw records with a manifest", "[bucket]") {
    ScratchDir dir;
    BucketOptions options;
    options.tmpDir = dir.path.string();
    options.keep = true;
    const std::vector<Triangle> input = generate(5000);
    std::string directory;
    {
        auto set = bucketize(input, BucketRanges({0.01f, 0.1f}), options);
        CHECK(set->kept());
        directory = set->directory();
        REQUIRE(fs::is_directory(directory));
        CHECK(fs::exists(directory + "/manifest.tsv"));
        for (const BucketInfo& b : set->buckets()) {
            REQUIRE(!b.path.empty());
            CHECK(fs::path(b.path).parent_path() == fs::path(directory));
            CHECK(fs::file_size(b.path) == b.bytes);
        }
        CHECK(fs::path(set->buckets()[0].path).filename() == "opaque-00.tri");
        CHECK(fs::path(set->buckets()[5].path).filename() == "alpha-02.tri");
    }
    // The set is gone, the files are not.
    CHECK(fs::exists(directory + "/opaque-00.tri"));
    CHECK(fs::exists(directory + "/manifest.tsv"));
    CHECK(dir.find("penumbra-buckets-").size() == 1);

    SECTION("a kept writer destroyed before finish removes its files and directory") {
        {
            BucketWriter writer(BucketRanges({0.01f}), options);
            writer.write(input);
            CHECK(dir.find("penumbra-buckets-").size() == 2);
        }
        CHECK(dir.find("penumbra-buckets-").size() == 1);
    }
    SECTION("a kept bucket cut short is reported on replay") {
        BucketOptions o = options;
        auto set = bucketize(input, BucketRanges({0.01f}), o);
        const BucketInfo& victim = set->buckets()[0];
        REQUIRE(victim.bytes > 400);
        fs::resize_file(victim.path, victim.bytes - 400);
        BucketReplaySource replay(set);
        std::string message = errorOf([&] { replayAll(replay, 4096); });
        CHECK_THAT(message, Catch::StartsWith(set->directory() + ": bucket 0 is shorter than written"));
    }
}

TEST_CASE("Bucket setup errors are one line naming the directory", "[bucket]") {
    ScratchDir dir;
    BucketOptions options;
    options.tmpDir = (dir.path / "missing" / "deeper").string();
    std::string message = errorOf([&] { BucketWriter w(BucketRanges(), options); });
    CHECK_THAT(message, Catch::StartsWith(options.tmpDir + ": cannot create bucket directory: No such file or directory"));

    options.tmpDir = dir.path.string();
    options.buckets = 0;
    CHECK_THAT(errorOf([&] { BucketWriter w(BucketRanges(), options); }), Catch::Contains("buckets must be between 1 and"));
    options.buckets = 32;
    options.writeBufferBytes = 8;
    CHECK_THAT(errorOf([&] { BucketWriter w(BucketRanges(), options); }), Catch::Contains("write buffer"));
    options.writeBufferBytes = 65536;

    BucketWriter writer(BucketRanges(), options);
    BucketSet set = writer.finish();
    CHECK_THROWS_AS(writer.write(generate(1)), std::logic_error);
    CHECK_THROWS_AS(writer.finish(), std::logic_error);
}

// --- the whole pass -------------------------------------------------------------------------

TEST_CASE("writeBuckets streams a source into buckets and reports the pass", "[bucket]") {
    ScratchDir dir;
    BucketOptions options;
    options.tmpDir = dir.path.string();
    GeneratedSource source(100000, 3);

    SECTION("quantile ranges from a histogram pass") {
        AreaHistogram h = histogramOf(source);
        BucketRanges ranges = planBucketRanges(options, &h);
        CHECK(ranges.count() == 32);
        uint64_t seen = 0;
        BucketStats stats;
        auto set = std::make_shared<BucketSet>(
            writeBuckets(source, ranges, options, &stats, [&](std::span<const Triangle> c) { seen += c.size(); }));
        CHECK(seen == 100000);
        CHECK(stats.triangles == 100000);
        CHECK(stats.opaqueTriangles + stats.alphaMatteTriangles == 100000);
        CHECK(stats.bytesWritten == 100000 * sizeof(Triangle));
        CHECK(stats.bytesPerTriangle() == 40.0);
        CHECK(stats.ranges == 32);
        CHECK(stats.nonEmptyFiles == 64);
        CHECK(stats.seconds > 0);
        CHECK(stats.writeSeconds <= stats.seconds);
        CHECK(stats.megabytesPerSecond() > 0);
        // Quantile ranges: opaque buckets hold similar counts (within 10% of an equal share,
        // as alpha-matte triangles are a fixed 1/7 of every range).
        for (size_t i = 0; i < 32; ++i)
            CHECK(std::abs(double(set->buckets()[i].triangles) - set->opaqueTriangles() / 32.0) <
                  0.1 * set->opaqueTriangles() / 32.0);
        BucketReplaySource replay(set, options.readBufferBytes);
        CHECK(replayAll(replay, kTriangleChunk).size() == 100000);
    }
    SECTION("fixed log2 ranges without a pre-pass") {
        BucketRanges ranges = planBucketRanges(options, nullptr, 1.0f);
        CHECK(ranges.splits() == AreaHistogram::fixedLog2Boundaries(32, 1.0f));
        BucketSet set = writeBuckets(source, ranges, options);
        CHECK(set.triangles() == 100000);
    }
    SECTION("a filter keeps the same triangles in stream order on any thread count") {
        // The pass filters chunks on several threads at once; what it writes must not depend on
        // that, and the chunk hook must still see every chunk once, in stream order.
        BucketRanges ranges = planBucketRanges(options, nullptr, 1.0f);
        auto keep = [](const Triangle& t) { return int(t.v[0].x) % 3 != 0; };  // about two thirds
        const std::vector<Triangle> all = generate(100000, 3);
        std::vector<Triangle> expected;
        for (const Triangle& t : all)
            if (keep(t)) expected.push_back(t);
        REQUIRE(expected.size() > 10000);
        REQUIRE(expected.size() < 90000);
        for (int threads : {1, 2}) {
            INFO(threads << " threads");
            tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
            source.rewind();
            std::vector<Triangle> hooked;
            BucketStats stats;
            auto set = std::make_shared<BucketSet>(writeBuckets(
                source, ranges, options, &stats, [&](std::span<const Triangle> c) { hooked.insert(hooked.end(), c.begin(), c.end()); },
                keep));
            REQUIRE(hooked.size() == all.size());
            CHECK(std::equal(hooked.begin(), hooked.end(), all.begin(), sameBytes));
            CHECK(stats.culledTriangles == all.size() - expected.size());
            // Each bucket holds its triangles in stream order, so a stable sort of the expected
            // triangles by bucket gives the replay (largest first: buckets in reverse).
            std::vector<Triangle> byBucket = expected;
            auto bucketOrder = [&](const Triangle& t) {
                return ((t.flags & kTriangleAlphaMatte) ? ranges.count() : 0) + ranges.bucketOf(t.area());
            };
            std::stable_sort(byBucket.begin(), byBucket.end(),
                             [&](const Triangle& a, const Triangle& b) { return bucketOrder(a) < bucketOrder(b); });
            BucketReplaySource replay(set, options.readBufferBytes);
            const std::vector<Triangle> replayed = replayAll(replay, kTriangleChunk);
            REQUIRE(replayed.size() == byBucket.size());
            CHECK(std::equal(replayed.begin(), replayed.end(), byBucket.begin(), sameBytes));
        }
    }
    SECTION("an error from the chunk hook removes everything") {
        BucketRanges ranges = planBucketRanges(options, nullptr);
        CHECK_THROWS_AS(writeBuckets(source, ranges, options, nullptr,
                                     [](std::span<const Triangle>) { fail("scene.json", "bad triangle"); }),
                        InputError);
        CHECK(dir.find("").empty());
    }
}

// --- full disk and signals, in child processes ----------------------------------------------

TEST_CASE("Bucket helper: file size limit", "[.][bucket-fsize-helper]") {
    if (!helperDir()) return;
    for (bool keep : {false, true}) {
        BucketOptions options;
        options.tmpDir = helperDir();
        options.keep = keep;
        GeneratedSource source(200000);  // 8 MB over 4 ranges: some file passes the 1 MiB limit
        std::string message = errorOf([&] { writeBuckets(source, BucketRanges({0.01f, 0.1f, 1.0f}), options); });
        std::cout << "bucket error: " << message << "\n";
        CHECK_THAT(message, Catch::Matches(std::string(helperDir()) +
                                           "/penumbra-buckets-[0-9]+-[0-9]+: cannot write (alpha-matte )?bucket [0-9]+: "
                                           "File too large \\(needed [0-9]+ more bytes\\)"));
        CHECK(message.find('\n') == std::string::npos);
        CHECK(fs::is_empty(helperDir()));
    }
}

TEST_CASE("A full disk gives one line naming the bucket directory and leaves nothing", "[bucket]") {
    ScratchDir dir;
    std::string output;
    int status = runHelper("[bucket-fsize-helper]", dir.path.string(), 1 << 20, output);
    INFO(output);
    REQUIRE(WIFEXITED(status));
    CHECK(WEXITSTATUS(status) == 0);
    CHECK_THAT(output, Catch::Contains("File too large (needed "));
    CHECK(dir.find("").empty());
}

TEST_CASE("Bucket helper: killed by SIGTERM", "[.][bucket-signal-helper]") {
    if (!helperDir()) return;
    installCleanupSignalHandlers();
    BucketOptions options;
    options.tmpDir = helperDir();
    options.keep = std::getenv("PENUMBRA_BUCKET_HELPER_KEEP") != nullptr;
    BucketWriter writer(BucketRanges({0.01f, 0.1f}), options);
    std::vector<Triangle> tris = generate(100000);
    writer.write(tris);
    REQUIRE(writer.bytesWritten() > 0);  // data really is on disk when the signal comes
    ::raise(SIGTERM);
    FAIL("still alive after SIGTERM");
}

TEST_CASE("SIGTERM during the bucket pass leaves no bucket files", "[bucket]") {
    for (bool keep : {false, true}) {
        CAPTURE(keep);
        ScratchDir dir;
        if (keep) ::setenv("PENUMBRA_BUCKET_HELPER_KEEP", "1", 1);
        std::string output;
        int status = runHelper("[bucket-signal-helper]", dir.path.string(), 0, output);
        ::unsetenv("PENUMBRA_BUCKET_HELPER_KEEP");
        INFO(output);
        REQUIRE(WIFSIGNALED(status));
        CHECK(WTERMSIG(status) == SIGTERM);
        if (!keep) {
            CHECK(dir.find("").empty());
        } else {
            // The registry unlinks files only: kept mode's directory may remain, empty.
            CHECK(dir.find("opaque-").empty());
            CHECK(dir.find("alpha-").empty());
        }
    }
}
