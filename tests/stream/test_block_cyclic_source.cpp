// TriangleSource::skip() and BlockCyclicSource (#18: a by-blockers shard makes only its share):
// skipping k triangles leaves exactly the stream after them, for every source that jumps instead
// of reading, and the N shares of a stream hold every triangle once, in stream order.

#include "TestSupport.h"

#include "procedural/GrassGenerator.h"
#include "procedural/ScatterGenerator.h"
#include "stream/BlockCyclicSource.h"
#include "stream/PtriFormat.h"
#include "stream/Transform.h"

#include <catch2/catch.hpp>

#include <cstring>
#include <functional>

using namespace penumbra;
using penumbra::test::ScratchDir;

namespace {

std::vector<Triangle> numbered(size_t n, size_t from = 0) {
    std::vector<Triangle> t(n);
    for (size_t i = 0; i < n; ++i) t[i].v[0] = glm::vec3(float(from + i), 1.0f, 2.0f), t[i].v[1] = glm::vec3(0, 0, float(i));
    return t;
}

bool same(std::span<const Triangle> a, std::span<const Triangle> b) {
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size_bytes()) == 0);
}

/// Everything @p s hands out from where it is, read in odd-sized chunks.
std::vector<Triangle> rest(TriangleSource& s) {
    std::vector<Triangle> all, chunk(37);
    while (size_t n = s.read(chunk)) all.insert(all.end(), chunk.begin(), chunk.begin() + ptrdiff_t(n));
    return all;
}

using Make = std::function<TriangleSourcePtr()>;

/// skip(k) then the rest equals the whole stream without its first k, from the start, after a
/// partial read and after a rewind.
void checkSkips(const Make& make) {
    TriangleSourcePtr whole = make();
    const std::vector<Triangle> all = rest(*whole);
    const size_t n = all.size();
    REQUIRE(n > 0);
    for (size_t k : {size_t(0), size_t(1), size_t(4), size_t(5), size_t(17), size_t(64), n / 2, n - 1, n, n + 9}) {
        TriangleSourcePtr s = make();
        const size_t expect = std::min(k, n);
        CHECK(s->skip(k) == expect);
        CHECK(same(rest(*s), std::span(all).subspan(expect)));
        // A read, a skip, the rest; then the same again after a rewind.
        for (int pass = 0; pass < 2; ++pass) {
            s->rewind();
            std::vector<Triangle> head(std::min<size_t>(3, n));
            REQUIRE(s->read(head) == head.size());
            const size_t skipped = s->skip(k);
            CHECK(skipped == std::min(k, n - head.size()));
            CHECK(same(rest(*s), std::span(all).subspan(head.size() + skipped)));
        }
    }
}

}  // namespace

TEST_CASE("skip() leaves the stream after the skipped triangles, for every source that jumps", "[stream]") {
    SECTION("vector") { checkSkips([] { return std::make_unique<VectorSource>(numbered(150)); }); }
    SECTION("concatenation, with an empty part") {
        checkSkips([] {
            std::vector<TriangleSourcePtr> parts;
            parts.push_back(std::make_unique<VectorSource>(numbered(5)));
            parts.push_back(std::make_unique<VectorSource>(numbered(0)));
            parts.push_back(std::make_unique<VectorSource>(numbered(70, 5)));
            return std::make_unique<ConcatSource>(std::move(parts));
        });
    }
    SECTION("flags and transform") {
        checkSkips([] {
            auto flagged = std::make_unique<FlagSource>(std::make_unique<VectorSource>(numbered(90)), kTriangleClosed, 0);
            return std::make_unique<TransformedSource>(std::move(flagged), glm::mat4(2.0f));
        });
    }
    SECTION("a generator of 5-triangle items, cut inside items") {
        GrassParams grass;
        grass.placement.count = 41;
        checkSkips([grass] { return makeGrassSource(grass); });
    }
    SECTION("a streamed scatter (instances skipped whole and in part)") {
        ScatterParams scatter;
        scatter.placement.count = 7;
        scatter.cacheTriangles = 0;  // stream the source once per instance
        checkSkips([scatter] { return makeScatterSource(scatter, std::make_unique<VectorSource>(numbered(23)), "test"); });
    }
    SECTION(".ptri, whole chunks jumped by seeking") {
        ScratchDir dir("skip-ptri");
        const std::string path = dir / "t.ptri";
        {
            PtriWriter w(path, 16);
            const std::vector<Triangle> t = numbered(203);
            w.write(t);
            w.finish();
        }
        checkSkips([path] { return openPtri(path); });
    }
}

TEST_CASE("the N shares of a stream hold every triangle once, in order, and know their size", "[stream]") {
    const std::vector<Triangle> all = numbered(1000);
    for (uint32_t count : {1u, 2u, 3u, 8u})
        for (uint64_t block : {uint64_t(1), uint64_t(7), uint64_t(64), uint64_t(5000)}) {
            std::vector<Triangle> joined;
            std::vector<std::vector<Triangle>> shares;
            for (uint32_t i = 0; i < count; ++i) {
                BlockCyclicSource share(std::make_unique<VectorSource>(all), BlockShare{i, count, block});
                shares.push_back(rest(share));
                CHECK(share.sizeHint() == shares.back().size());
                share.rewind();  // the same share again
                CHECK(same(rest(share), shares.back()));
            }
            // Dealing the blocks back out in turn gives the stream.
            std::vector<size_t> at(count, 0);
            for (size_t k = 0; joined.size() < all.size(); ++k) {
                std::vector<Triangle>& s = shares[k % count];
                const size_t n = std::min<size_t>(block, s.size() - at[k % count]);
                joined.insert(joined.end(), s.begin() + ptrdiff_t(at[k % count]), s.begin() + ptrdiff_t(at[k % count] + n));
                at[k % count] += n;
                REQUIRE(k < all.size() + count);
            }
            INFO(count << " shares of blocks of " << block);
            CHECK(same(joined, all));
        }
    CHECK(blockSizeForShares(100, 4) == 64);
    CHECK(blockSizeForShares(100'000'000, 4) == 65536);
    CHECK(blockSizeForShares(1'000'000, 4) == 3906);
}
