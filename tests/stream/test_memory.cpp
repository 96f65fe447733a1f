// Tests for byte-size parsing and the RSS probes.

#include "stream/util/Error.h"
#include "stream/util/Memory.h"

#include "TestSupport.h"

#include <catch2/catch.hpp>

#include <functional>
#include <memory>

using namespace penumbra::test;
using penumbra::InputError;
using penumbra::parseByteSize;


TEST_CASE("parseByteSize accepts plain counts and binary units", "[io]") {
    constexpr uint64_t K = 1024, M = K * K, G = M * K, T = G * K;
    CHECK(parseByteSize("1000", "x") == 1000);
    CHECK(parseByteSize("0", "x") == 0);
    CHECK(parseByteSize("512k", "x") == 512 * K);
    CHECK(parseByteSize("512K", "x") == 512 * K);
    CHECK(parseByteSize("256M", "x") == 256 * M);
    CHECK(parseByteSize("256MB", "x") == 256 * M);
    CHECK(parseByteSize("1G", "x") == G);
    CHECK(parseByteSize("1.5GiB", "x") == 3 * G / 2);
    CHECK(parseByteSize("2 GB", "x") == 2 * G);
    CHECK(parseByteSize("  64mib  ", "x") == 64 * M);
    CHECK(parseByteSize("3T", "x") == 3 * T);
    CHECK(parseByteSize("10b", "x") == 10);
    CHECK(parseByteSize("10 B", "x") == 10);
    CHECK(parseByteSize("+7k", "x") == 7 * K);
    CHECK(parseByteSize("0.5k", "x") == 512);
    CHECK(parseByteSize(".5M", "x") == M / 2);
    CHECK(parseByteSize("1.0000001k", "x") == 1024);  // fractions of a byte round down
    CHECK(parseByteSize("18446744073709551615", "x") == UINT64_MAX);
}

TEST_CASE("parseByteSize rejects malformed text naming the setting", "[io]") {
    const char* bad[] = {"", "   ", "abc", "-1", "-1G", "1.5", "12Q", "1e9", "1,5G", "M", ".", "1..5G",
                         "1 G B", "1Gi", "1GiBs", "18446744073709551616", "20000000T", "1e400G", "nanG", "inf"};
    for (const char* text : bad) {
        INFO("'" << text << "'");
        std::string msg = errorOf([&] { parseByteSize(text, "--memory"); });
        CHECK(msg.rfind(std::string("--memory: '") + text + "' is not a byte size (", 0) == 0);
        CHECK(msg.find('\n') == std::string::npos);
    }
    CHECK(errorOf([&] { parseByteSize("12Q", "scene.json: memory_budget"); }) ==
          "scene.json: memory_budget: '12Q' is not a byte size (unknown unit 'Q'; expected e.g. "
          "1000, 512k, 256M or 1.5GiB)");
}

TEST_CASE("formatBytes", "[io]") {
    CHECK(penumbra::formatBytes(0) == "0 B");
    CHECK(penumbra::formatBytes(1023) == "1023 B");
    CHECK(penumbra::formatBytes(1536) == "1.50 KiB");
    CHECK(penumbra::formatBytes(25 * 1024 * 1024) == "25.0 MiB");
    CHECK(penumbra::formatBytes(256ull << 20) == "256 MiB");
    CHECK(penumbra::formatBytes(3ull << 30) == "3.00 GiB");
}

TEST_CASE("peakRssBytes grows after touching a large buffer", "[io]") {
    const uint64_t before = penumbra::peakRssBytes();
    const uint64_t current = penumbra::currentRssBytes();
    REQUIRE(before > 0);
    REQUIRE(current > 0);
    CHECK(current <= before + (4u << 20));  // statm and rusage agree to within a few pages

    // Earlier tests may have pushed the peak above the current RSS; allocate enough to pass
    // the old peak by at least 64 MiB whatever happened before.
    constexpr size_t kMiB = 1 << 20;
    const size_t size = static_cast<size_t>(before > current ? before - current : 0) + 64 * kMiB;
    std::unique_ptr<uint8_t[]> buffer(new uint8_t[size]);
    volatile uint8_t* p = buffer.get();
    for (size_t i = 0; i < size; i += 4096) p[i] = static_cast<uint8_t>(i >> 12);

    CHECK(penumbra::currentRssBytes() >= current + 48 * kMiB);
    CHECK(penumbra::peakRssBytes() >= before + 48 * kMiB);
    uint64_t sum = 0;
    for (size_t i = 0; i < size; i += 4096) sum += p[i];
    CHECK(sum > 0);
}
