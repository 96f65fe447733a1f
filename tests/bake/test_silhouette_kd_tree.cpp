// The kd-tree of ssv: its byte limit bounds the tree when items overlap without separating, and
// queries still reach every item whose box holds the point.

#include "bake/methods/SilhouetteKdTree.h"

#include <catch2/catch.hpp>

#include <set>

using namespace penumbra;

namespace {

/// @p n boxes of the edges between six points, many copies of each, as in a fan of triangles on
/// a few vertices: copies never separate, so splits go on while each lists them on both sides.
std::vector<KdItem> fan(uint32_t n) {
    const glm::dvec3 points[6] = {{0, 0, 0}, {1, 0.1, 0}, {0.2, 1, 0.3}, {-1, 0.4, -0.2}, {0.3, -1, 0.6}, {0.7, 0.6, -1}};
    std::vector<KdItem> items(n);
    for (uint32_t i = 0; i < n; ++i) {
        const int a = int(i % 6), b = int((i / 6 + 1 + i % 6) % 6);
        items[i].box.add(points[a]);
        items[i].box.add(points[a == b ? (a + 1) % 6 : b]);
        items[i].id = i;
    }
    return items;
}

std::set<uint32_t> itemsAt(const SilhouetteKdTree& tree, const glm::dvec3& p) {
    std::set<uint32_t> found;
    tree.visitPoint(p, 1e-9, [&](uint32_t leaf) {
        for (uint32_t id : tree.items(leaf, 0)) found.insert(id);
    });
    return found;
}

}  // namespace

TEST_CASE("kd-tree: the byte limit bounds a tree of overlapping items, and queries still find every item", "[ssv][kd]") {
    const uint32_t n = 4000;
    SilhouetteKdTree unlimited, limited;
    unlimited.build(fan(n));
    KdParams params;
    params.maxBytes = 40 * n;
    limited.build(fan(n), params);
    INFO("unlimited " << unlimited.bytes() << " bytes, limited " << limited.bytes());
    CHECK(unlimited.bytes() > params.maxBytes);  // the case the limit is for
    CHECK(limited.bytes() <= params.maxBytes);
    // The limit changes the leaves, never what a query can reach: every item whose box holds the
    // point is listed by a leaf holding it.
    const std::vector<KdItem> items = fan(n);
    for (const glm::dvec3& p : {glm::dvec3(0, 0, 0), glm::dvec3(0.3, 0.2, 0.1), glm::dvec3(-0.5, 0.1, -0.2), glm::dvec3(0.01, -0.7, 0)}) {
        std::set<uint32_t> expected;
        for (const KdItem& item : items)
            if (glm::all(glm::lessThanEqual(item.box.lo, p)) && glm::all(glm::lessThanEqual(p, item.box.hi))) expected.insert(item.id);
        const std::set<uint32_t> a = itemsAt(limited, p), b = itemsAt(unlimited, p);
        for (uint32_t id : expected) {
            CHECK(a.count(id) == 1);
            CHECK(b.count(id) == 1);
        }
    }
}
