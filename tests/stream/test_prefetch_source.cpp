// PrefetchSource: the same stream as the wrapped source, for any chunk sizes, across rewinds,
// with errors delivered in stream order.

#include "stream/util/Error.h"
#include "stream/PrefetchSource.h"

#include <catch2/catch.hpp>

using namespace penumbra;

namespace {

std::vector<Triangle> numbered(size_t n) {
    std::vector<Triangle> t(n);
    for (size_t i = 0; i < n; ++i) t[i].flags = uint32_t(i);
    return t;
}

/// Fails after delivering `good` triangles.
class FailingSource final : public TriangleSource {
public:
    explicit FailingSource(size_t good) : good_(good) {}
    size_t read(std::span<Triangle> out) override {
        if (next_ >= good_) throw InputError("broken.ptri: checksum mismatch in chunk 3");
        size_t n = std::min(out.size(), good_ - next_);
        for (size_t i = 0; i < n; ++i) out[i].flags = uint32_t(next_ + i);
        next_ += n;
        return n;
    }
    void rewind() override { next_ = 0; }
    std::string name() const override { return "broken.ptri"; }

private:
    size_t good_, next_ = 0;
};

}  // namespace

TEST_CASE("prefetching preserves the stream for any chunk sizes and rewinds", "[stream]") {
    for (size_t inner : {1, 7, 4096}) {
        for (size_t outer : {1, 5, 1000}) {
            PrefetchSource source(std::make_unique<VectorSource>(numbered(10007)), inner, 3);
            for (int pass = 0; pass < 2; ++pass) {
                std::vector<Triangle> chunk(outer);
                uint32_t expected = 0;
                while (size_t n = source.read(chunk))
                    for (size_t i = 0; i < n; ++i) REQUIRE(chunk[i].flags == expected++);
                CHECK(expected == 10007);
                CHECK(source.read(chunk) == 0);
                source.rewind();
            }
        }
    }
}

TEST_CASE("prefetching rethrows the inner source's error after the good triangles", "[stream]") {
    PrefetchSource source(std::make_unique<FailingSource>(100), 16, 2);
    std::vector<Triangle> chunk(30);
    size_t total = 0;
    try {
        while (size_t n = source.read(chunk)) total += n;
        FAIL("no error");
    } catch (const InputError& e) {
        CHECK(std::string(e.what()) == "broken.ptri: checksum mismatch in chunk 3");
    }
    CHECK(total == 100);
}

TEST_CASE("destroying a prefetching source mid-stream stops its thread", "[stream]") {
    for (int i = 0; i < 20; ++i) {
        PrefetchSource source(std::make_unique<VectorSource>(numbered(100000)), 64, 2);
        std::vector<Triangle> chunk(10);
        source.read(chunk);
    }
    SUCCEED();
}

TEST_CASE("prefetching keeps the parts of a concatenation apart: one part per read and its index", "[stream]") {
    const size_t sizes[] = {5000, 3, 0, 7001};
    for (size_t inner : {1, 7, 4096}) {
        std::vector<TriangleSourcePtr> parts;
        for (size_t n : sizes) parts.push_back(std::make_unique<VectorSource>(numbered(n)));
        PrefetchSource source(std::make_unique<ConcatSource>(std::move(parts)), inner, 3);
        for (int pass = 0; pass < 2; ++pass) {
            std::vector<Triangle> chunk(4096);
            std::vector<size_t> seen(std::size(sizes), 0);
            uint32_t last = 0;
            while (size_t n = source.read(chunk)) {
                const uint32_t part = source.part();
                REQUIRE(part < std::size(sizes));
                REQUIRE(part >= last);  // in order
                for (size_t i = 0; i < n; ++i) REQUIRE(chunk[i].flags == uint32_t(seen[part] + i));  // not mixed
                seen[part] += n, last = part;
            }
            for (size_t p = 0; p < std::size(sizes); ++p) CHECK(seen[p] == sizes[p]);
            source.rewind();
        }
    }
}
