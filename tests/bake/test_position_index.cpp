// PositionIndex (smooth shading's flat vertex table) against std::unordered_map.

#include "bake/shading/PositionIndex.h"

#include <catch2/catch.hpp>

#include <random>
#include <unordered_map>

using namespace penumbra;

namespace {
struct KeyHash {
    size_t operator()(const PositionKey& k) const { return k.hash(); }
};
}  // namespace

TEST_CASE("the position index keeps every key's value through growth, as a map does", "[shading]") {
    std::mt19937 rng(17);
    // Few distinct words, so keys repeat and collide in the low bits: probing chains get long.
    std::uniform_int_distribution<uint32_t> word(0, 40);
    std::unordered_map<PositionKey, uint32_t, KeyHash> expected;
    PositionIndex index;
    CHECK(index.find({1, 2, 3}) == PositionIndex::kEmpty);  // empty table
    for (uint32_t n = 0; n < 30000; ++n) {
        const PositionKey key{word(rng), word(rng), word(rng) * 0x01000193u};
        uint32_t& value = index.findOrInsert(key);
        auto [it, inserted] = expected.try_emplace(key, PositionIndex::kEmpty);
        REQUIRE(value == it->second);
        value = it->second = n;  // the latest, as VertexBend keeps a position's latest slot
    }
    CHECK(index.size() == expected.size());
    for (const auto& [key, value] : expected) CHECK(index.find(key) == value);
    CHECK(index.find({41, 41, 41}) == PositionIndex::kEmpty);
    size_t used = 0;
    for (const PositionIndex::Entry& e : index.entries()) used += e.value != PositionIndex::kEmpty;
    CHECK(used == expected.size());
    // At most three quarters full, and within the bytes the memory plan counts per key.
    CHECK(4 * index.size() <= 3 * index.entries().size());
    CHECK(index.bytes() <= PositionIndex::kPeakBytesPerKey * index.size());
}
