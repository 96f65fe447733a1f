// Tests for the .ptri binary triangle stream: layout, round trips, atomic writing, write
// errors, and a reader that rejects every truncation and every single-byte corruption.

#include "stream/Error.h"
#include "stream/AtomicFile.h"
#include "stream/PtriFormat.h"
#include "StreamTestFiles.h"

#include <catch2/catch.hpp>

#include <csignal>
#include <limits>
#include <random>

#include <sys/resource.h>

using namespace penumbra;
using namespace penumbra::testing;

namespace {

std::vector<Triangle> someTriangles(size_t count, uint32_t seed = 1) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> coordinate(-100.0f, 100.0f);
    std::vector<Triangle> tris(count);
    for (size_t i = 0; i < count; ++i) {
        for (auto& p : tris[i].v) p = {coordinate(rng), coordinate(rng), coordinate(rng)};
        tris[i].flags = i % 3 == 0 ? uint32_t(kTriangleAlphaMatte) : 0u;
    }
    return tris;
}

void writePtri(const std::string& path, const std::vector<Triangle>& tris, uint32_t chunkSize = kPtriDefaultChunk) {
    PtriWriter writer(path, chunkSize);
    writer.write(tris);
    writer.finish();
}

/// The message a full read of @p path gives, or "no error".
std::string readError(const std::string& path) {
    try {
        TriangleSourcePtr source = openPtri(path);
        readAll(*source);
    } catch (const InputError& e) {
        return e.what();
    }
    return "no error";
}

template <typename T>
void put(std::vector<uint8_t>& bytes, size_t offset, T value) {
    std::memcpy(bytes.data() + offset, &value, sizeof value);
}

/// Recomputes the header checksum after a deliberate edit, so deeper checks are reached.
void resealHeader(std::vector<uint8_t>& bytes) { put(bytes, 44, fnv1a32(bytes.data(), 44)); }

/// Recomputes the checksum of the chunk at @p offset (count field + payload).
void resealChunk(std::vector<uint8_t>& bytes, size_t offset) {
    uint32_t count;
    std::memcpy(&count, &bytes[offset], 4);
    uint32_t hash = fnv1a32(&bytes[offset], 4);
    put(bytes, offset + 4, fnv1a32(&bytes[offset + 8], size_t(count) * 40, hash));
}

}  // namespace

TEST_CASE("PTRI: FNV-1a 32 reference values", "[stream][ptri]") {
    CHECK(fnv1a32("", 0) == 0x811c9dc5u);
    CHECK(fnv1a32("a", 1) == 0xe40c292cu);
    CHECK(fnv1a32("foobar", 6) == 0xbf9cf968u);
    CHECK(fnv1a32("bar", 3, fnv1a32("foo", 3)) == 0xbf9cf968u);  // chaining
}

TEST_CASE("PTRI: round trip is bit-exact across chunk boundaries", "[stream][ptri]") {
    TempDir dir("ptri");
    for (size_t count : {0, 1, 6, 7, 8, 50}) {
        INFO("count " << count);
        std::vector<Triangle> tris = someTriangles(count);
        writePtri(dir.file("a.ptri"), tris, 7);
        TriangleSourcePtr source = openPtri(dir.file("a.ptri"));
        CHECK(source->sizeHint() == count);
        CHECK(source->name() == dir.file("a.ptri"));
        CHECK(sameBits(readAll(*source), tris));

        // Reads of odd sizes straddle chunks; rewind replays from the start.
        for (size_t span : {1, 3, 13}) {
            source->rewind();
            std::vector<Triangle> pieces, buffer(span);
            while (size_t n = source->read(buffer)) pieces.insert(pieces.end(), buffer.begin(), buffer.begin() + n);
            CHECK(sameBits(pieces, tris));
        }
    }
}

TEST_CASE("PTRI: the header and chunks follow the documented layout", "[stream][ptri]") {
    TempDir dir("ptri");
    std::vector<Triangle> tris = someTriangles(10);
    tris[4].v[1] = {-500, 600, 0.5f};
    writePtri(dir.file("a.ptri"), tris, 4);
    std::vector<uint8_t> bytes = readBytes(dir.file("a.ptri"));
    REQUIRE(bytes.size() == 48 + 3 * 8 + 10 * 40);

    auto get32 = [&](size_t offset) {
        uint32_t v;
        std::memcpy(&v, &bytes[offset], 4);
        return v;
    };
    CHECK(std::memcmp(bytes.data(), "PTRI", 4) == 0);
    CHECK(get32(4) == 1u);
    uint64_t count;
    std::memcpy(&count, &bytes[8], 8);
    CHECK(count == 10u);
    CHECK(get32(40) == 4u);
    CHECK(get32(44) == fnv1a32(bytes.data(), 44));

    PtriInfo info = readPtriHeader(dir.file("a.ptri"));
    CHECK(info.triangles == 10u);
    CHECK(info.chunkSize == 4u);
    CHECK(info.chunkCount() == 3u);
    CHECK(info.fileBytes() == bytes.size());
    CHECK(info.lo.x == -500.0f);
    CHECK(info.hi.y == 600.0f);
    for (const Triangle& t : tris)
        for (const auto& p : t.v) CHECK(glm::all(glm::lessThanEqual(info.lo, p) & glm::lessThanEqual(p, info.hi)));

    size_t offset = 48;
    for (uint32_t expected : {4u, 4u, 2u}) {
        CHECK(get32(offset) == expected);
        uint32_t hash = fnv1a32(&bytes[offset], 4);
        CHECK(get32(offset + 4) == fnv1a32(&bytes[offset + 8], expected * 40, hash));
        offset += 8 + expected * 40;
    }
    // The payload is Triangle records verbatim.
    CHECK(std::memcmp(&bytes[48 + 8], tris.data(), 4 * 40) == 0);

    PtriInfo empty;
    empty.triangles = 0;
    CHECK(empty.fileBytes() == 48u);
}

TEST_CASE("PTRI: writing is atomic", "[stream][ptri]") {
    TempDir dir("ptri");
    std::string path = dir.file("scene.ptri");
    writeText(path, "previous contents");
    {
        PtriWriter writer(path, 4);
        writer.write(someTriangles(9));
        CHECK(readBytes(path).size() == std::string("previous contents").size());  // untouched so far
        // The temporary has no name at all (O_TMPFILE), except where the file system lacks it.
        CHECK(dir.entries().size() == (anonymousFilesDisabled() ? 2u : 1u));
        // Destroyed without finish(): as if an exception had unwound the conversion.
    }
    CHECK(dir.entries() == std::vector<std::string>{"scene.ptri"});
    CHECK(readBytes(path).size() == std::string("previous contents").size());

    {
        PtriWriter writer(path, 4);
        writer.write(someTriangles(9));
        writer.finish();
        CHECK(writer.triangleCount() == 9u);
        CHECK_THROWS_AS(writer.finish(), InputError);
        CHECK_THROWS_AS(writer.write(someTriangles(1)), InputError);
    }
    CHECK(dir.entries() == std::vector<std::string>{"scene.ptri"});
    CHECK(readPtriHeader(path).triangles == 9u);
}

TEST_CASE("PTRI: writer rejects bad input and unwritable places", "[stream][ptri]") {
    TempDir dir("ptri");
    std::vector<Triangle> tris = someTriangles(3);
    tris[2].v[0].y = std::numeric_limits<float>::quiet_NaN();
    {
        PtriWriter writer(dir.file("nan.ptri"));
        try {
            writer.write(tris);
            FAIL("no error");
        } catch (const InputError& e) {
            CHECK(std::string(e.what()) == dir.file("nan.ptri") + ": triangle 2 has a non-finite coordinate");
        }
    }
    CHECK(dir.entries().empty());
    CHECK_THROWS_AS(PtriWriter(dir.file("no/such/dir/x.ptri")), InputError);
    CHECK_THROWS_AS(PtriWriter(dir.file("x.ptri"), 0), InputError);
    CHECK_THROWS_AS(PtriWriter(dir.file("x.ptri"), kPtriMaxChunk + 1), InputError);
}

TEST_CASE("PTRI: a full disk is reported with the path and the bytes not written", "[stream][ptri]") {
    // RLIMIT_FSIZE makes write(2) fail with EFBIG beyond the limit, the same path ENOSPC takes.
    // The limit is process-wide, so it is held only around the writes and nothing prints then.
    TempDir dir("ptri");
    std::string path = dir.file("big.ptri");
    std::vector<Triangle> tris = someTriangles(5000);
    rlimit old{};
    REQUIRE(::getrlimit(RLIMIT_FSIZE, &old) == 0);
    auto oldHandler = std::signal(SIGXFSZ, SIG_IGN);
    std::string message = "no error";
    {
        PtriWriter writer(path, 1024);
        rlimit limited = old;
        limited.rlim_cur = 64 * 1024;
        REQUIRE(::setrlimit(RLIMIT_FSIZE, &limited) == 0);
        try {
            writer.write(tris);
            writer.finish();
        } catch (const InputError& e) {
            message = e.what();
        }
        ::setrlimit(RLIMIT_FSIZE, &old);
    }
    std::signal(SIGXFSZ, oldHandler);
    INFO(message);
    CHECK(message.rfind(path + ": could not write ", 0) == 0);
    CHECK(message.find(" bytes: ") != std::string::npos);
    CHECK(dir.entries().empty());  // neither the output nor the temporary
}

TEST_CASE("PTRI: reader errors say what is wrong and where", "[stream][ptri]") {
    TempDir dir("ptri");
    std::string path = dir.file("scene.ptri");
    writePtri(path, someTriangles(20), 8);  // chunks of 8, 8, 4: 48 + 3 * 8 + 800 = 872 bytes
    const std::vector<uint8_t> good = readBytes(path);
    REQUIRE(good.size() == 872);
    const size_t chunk1 = 48 + 8 + 320, chunk2 = chunk1 + 8 + 320;

    CHECK(readError(dir.file("missing.ptri")).rfind(dir.file("missing.ptri") + ": cannot open", 0) == 0);

    auto check = [&](std::vector<uint8_t> bytes, const std::string& expected) {
        writeBytes(path, bytes);
        CHECK(readError(path) == path + ": " + expected);
    };
    auto edited = [&](auto edit) {
        std::vector<uint8_t> bytes = good;
        edit(bytes);
        return bytes;
    };
    check(edited([](auto& b) { b[0] = 'X'; }), "not a .ptri file (bad magic)");
    check(edited([](auto& b) { put<uint32_t>(b, 4, 2); }), "unsupported .ptri version 2 (this build reads version 1)");
    check(edited([](auto& b) { b[20] ^= 1; }), "header checksum mismatch");
    check(edited([](auto& b) { b[44] ^= 1; }), "header checksum mismatch");
    check(std::vector<uint8_t>(good.begin(), good.begin() + 30), "truncated header (expected 48 bytes, found 30)");
    check(std::vector<uint8_t>(good.begin(), good.begin() + chunk2 + 100),
          "truncated in chunk 2 (expected 168 bytes, found 100)");
    check(std::vector<uint8_t>(good.begin(), good.begin() + chunk1 + 3),
          "truncated in chunk 1 (expected 328 bytes, found 3)");
    check(edited([](auto& b) { b.push_back(0); }), "1 unexpected bytes after the last chunk (file has 873, header implies 872)");
    check(edited([&](auto& b) { b[chunk1 + 8 + 17] ^= 0x40; }), "checksum mismatch in chunk 1");
    check(edited([&](auto& b) { b[chunk2 + 4] ^= 0x40; }), "checksum mismatch in chunk 2");
    check(edited([&](auto& b) { b[chunk2] ^= 0x01; }), "chunk 2 holds 5 triangles, expected 4");
    // Deeper checks, reached by resealing the checksums an edit invalidates.
    check(edited([](auto& b) { put<uint32_t>(b, 40, 0), resealHeader(b); }), "invalid chunk size 0 (must be 1..1048576)");
    check(edited([](auto& b) { put<uint32_t>(b, 40, kPtriMaxChunk + 1), resealHeader(b); }),
          "invalid chunk size 1048577 (must be 1..1048576)");
    check(edited([](auto& b) { put<uint64_t>(b, 8, ~0ull), resealHeader(b); }),
          "implausible triangle count 18446744073709551615");
    check(edited([&](auto& b) {
              put<float>(b, chunk1 + 8 + 40 * 3 + 4, std::numeric_limits<float>::infinity());
              resealChunk(b, chunk1);
          }),
          "chunk 1 triangle 3 has a non-finite coordinate");
    // A count edited consistently with its checksum still cannot misalign the stream.
    check(edited([&](auto& b) { put<uint32_t>(b, chunk1, 7), resealChunk(b, chunk1); }), "chunk 1 holds 7 triangles, expected 8");

    // Errors surface at open for everything the header and file size reveal.
    writeBytes(path, std::vector<uint8_t>(good.begin(), good.end() - 1));
    CHECK_THROWS_AS(openPtri(path), InputError);
    CHECK_THROWS_AS(readPtriHeader(path), InputError);
}

TEST_CASE("PTRI: every truncated prefix is rejected", "[stream][ptri][robustness]") {
    TempDir dir("ptri");
    std::string path = dir.file("cut.ptri");
    writePtri(path, someTriangles(10), 4);  // three chunks, the last one partial
    const std::vector<uint8_t> good = readBytes(path);
    for (size_t length = 0; length < good.size(); ++length) {
        writeBytes(path, good.data(), length);
        INFO("prefix of " << length << " bytes");
        CHECK_THROWS_AS(openPtri(path), InputError);
    }
    writeBytes(path, good);
    CHECK(readError(path) == "no error");
}

TEST_CASE("PTRI: every single-byte corruption is rejected", "[stream][ptri][robustness]") {
    TempDir dir("ptri");
    std::string path = dir.file("flip.ptri");
    writePtri(path, someTriangles(10), 4);
    const std::vector<uint8_t> good = readBytes(path);
    for (size_t i = 0; i < good.size(); ++i)
        for (uint8_t mask : {0x01, 0xFF}) {
            std::vector<uint8_t> bytes = good;
            bytes[i] ^= mask;
            writeBytes(path, bytes);
            INFO("byte " << i << " ^ " << int(mask));
            CHECK(readError(path) != "no error");
        }
}

TEST_CASE("PTRI: sources hold no descriptor between passes", "[stream][ptri]") {
    TempDir dir("ptri");
    std::string path = dir.file("a.ptri");
    writePtri(path, someTriangles(10), 4);
    auto openDescriptors = [] {
        return std::distance(std::filesystem::directory_iterator("/proc/self/fd"), std::filesystem::directory_iterator());
    };
    auto before = openDescriptors();
    std::vector<TriangleSourcePtr> sources;
    for (int i = 0; i < 50; ++i) sources.push_back(openPtri(path));
    CHECK(openDescriptors() == before);
    std::vector<Triangle> three(3);
    CHECK(sources[0]->read(three) == 3);  // mid-pass: open
    CHECK(openDescriptors() == before + 1);
    readAll(*sources[0]);  // finished: closed again
    CHECK(openDescriptors() == before);
    sources[1]->read(three);
    sources[1]->rewind();
    CHECK(openDescriptors() == before);
    CHECK(sameBits(readAll(*sources[1]), readAll(*openPtri(path))));
}
