// The receiver BVH: boxes contain their receivers, leaves hold <= leafSize, every receiver
// appears once, umbra bits fold up, and rebuilds drop fully shadowed receivers.

#include "TestScenes.h"

#include "bake/cast/MaskPool.h"
#include "bake/cast/ReceiverHierarchy.h"

#include <catch2/catch.hpp>

#include <set>

using namespace penumbra;
using namespace penumbra::test;

namespace {

std::vector<ReceiverInput> inputs(const ReceiverSet& r) {
    std::vector<ReceiverInput> in;
    for (uint32_t i = 0; i < r.size(); ++i) in.push_back({glm::dvec3(r.position[i]), 1e-5, i, i % 4});
    return in;
}

void checkStructure(const ReceiverHierarchy& h, int leafSize) {
    std::set<uint32_t> seen;
    std::vector<uint32_t> stack = {0};
    while (!stack.empty()) {
        const auto& n = h.nodes[stack.back()];
        stack.pop_back();
        if (n.leaf()) {
            CHECK(int(n.count) <= leafSize);
            for (uint32_t r = n.first; r < n.first + n.count; ++r) {
                const glm::dvec3& p = h.position[r];
                for (int a = 0; a < 3; ++a) {
                    REQUIRE(double(n.lo[a]) <= p[a]);
                    REQUIRE(double(n.hi[a]) >= p[a]);
                }
                CHECK(seen.insert(r).second);
            }
        } else {
            for (uint32_t c : {n.first, n.first + 1}) {
                const auto& child = h.nodes[c];
                for (int a = 0; a < 3; ++a) {
                    CHECK(child.lo[a] >= n.lo[a]);
                    CHECK(child.hi[a] <= n.hi[a]);
                }
                stack.push_back(c);
            }
        }
    }
    CHECK(seen.size() == h.liveCount());
}

}  // namespace

TEST_CASE("hierarchy boxes contain their receivers and leaves stay small", "[receivers]") {
    ReceiverSet r = randomReceivers(1, 5000, {-10, 0, -10}, {10, 1, 10});
    for (int leaf : {1, 4, 16}) {
        ReceiverHierarchy h(HierarchyParams{leaf, 1024}, 4);
        h.build(inputs(r));
        checkStructure(h, leaf);
        std::set<uint32_t> ids(h.id.begin(), h.id.end());
        CHECK(ids.size() == 5000);
    }
}

TEST_CASE("coincident receivers still split into small leaves", "[receivers]") {
    ReceiverSet r;
    for (int i = 0; i < 1000; ++i) r.position.push_back({1, 2, 3}), r.normal.push_back({0, 1, 0});
    ReceiverHierarchy h(HierarchyParams{16, 64}, 1);
    h.build(inputs(r));
    checkStructure(h, 16);
}

TEST_CASE("rebuild drops full-umbra receivers and keeps masks and group bits", "[receivers]") {
    ReceiverSet r = randomReceivers(2, 400, {0, 0, 0}, {1, 1, 1});
    ReceiverHierarchy h(HierarchyParams{8, 32}, 70);  // 70 groups: two umbra words
    h.build(inputs(r));
    MaskPool pool(70);
    std::set<uint32_t> umbraIds;
    for (size_t i = 0; i < h.liveCount(); i += 3) {
        h.fullUmbra[i] = 1, ++h.umbraCount;
        umbraIds.insert(h.id[i]);
    }
    // A survivor with a mask and a group bit in the second word.
    size_t keep = 1;
    uint32_t keepId = h.id[keep];
    h.mask[keep] = pool.allocate();
    pool.data(h.mask[keep])[69] = 5;
    h.groupUmbra[keep * 2 + 1] |= 1ull << 5;
    h.rebuild();
    CHECK(h.retired.size() == umbraIds.size());
    CHECK(std::set<uint32_t>(h.retired.begin(), h.retired.end()) == umbraIds);
    CHECK(h.liveCount() == 400 - umbraIds.size());
    checkStructure(h, 8);
    bool found = false;
    for (size_t i = 0; i < h.liveCount(); ++i)
        if (h.id[i] == keepId) {
            found = true;
            REQUIRE(h.mask[i] != MaskPool::kNone);
            CHECK(pool.data(h.mask[i])[69] == 5);
            CHECK(((h.groupUmbra[i * 2 + 1] >> 5) & 1) == 1);
        }
    CHECK(found);
}

TEST_CASE("mask pool hands out zeroed masks and reuses released slots", "[receivers]") {
    MaskPool pool(3);
    uint32_t a = pool.allocate(), b = pool.allocate();
    CHECK(a != b);
    pool.data(a)[2] = 7;
    pool.release(a);
    CHECK(pool.live() == 1);
    uint32_t c = pool.allocate();
    CHECK(c == a);
    CHECK(pool.data(c)[2] == 0);
    CHECK(pool.peakLive() == 2);
    for (int i = 0; i < 10000; ++i) pool.allocate();  // crosses block boundaries
    CHECK(pool.live() == 10002);
    CHECK(pool.data(b)[0] == 0);
}
