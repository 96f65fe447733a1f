// "grid" (the paper's GRIDS) through the registry: deterministic for any thread count, the
// documented triangle count, and clean errors. Its exactness is covered in test_hpc_exactness.cpp.

#include "ProceduralTestUtil.h"

using namespace penumbra;
using namespace penumbra::test;

TEST_CASE("grid: deterministic, documented count, sane triangles", "[procedural]") {
    const nlohmann::json e = {{"type", "grid"}, {"cells", 20}, {"levels", 3}, {"thickness", 0.04}, {"floor_size", 10}};
    requireDeterministic(e);
    requireDeterministic({{"type", "grid"}, {"cells", 7}, {"levels", 2}, {"thickness", 0}});
    TriangleSourcePtr source = openEntry(e);
    CHECK(source->sizeHint() == 2u + 3u * 21 * 21 * 12);
    StreamSummary s = summarise(*source);
    CHECK(s.count == 2u + 3u * 21 * 21 * 12);
    CHECK(s.nonFinite == 0);
    CHECK(s.degenerate == 0);
    CHECK(s.lo.x == -5.0);
    CHECK(s.hi.z == 5.0);
    CHECK(s.lo.y == 0.0);
    CHECK(s.hi.y == Approx(1.0 + 2 * 0.6 + 0.02));
}

TEST_CASE("grid: bars are closed boxes wound outward, the floor and flat bars are not marked", "[procedural]") {
    StreamSummary s = summarise(*openEntry({{"type", "grid"}, {"cells", 3}, {"levels", 2}, {"thickness", 0.05}, {"floor_size", 6}}), true);
    REQUIRE(s.triangles.size() == 2u + 2u * 4 * 4 * 12);
    for (size_t i = 0; i < s.triangles.size(); ++i) {
        const Triangle& t = s.triangles[i];
        INFO("triangle " << i);
        CHECK(bool(t.flags & kTriangleClosed) == (i >= 2));
        if (i < 2) continue;
        // Outward: the normal points away from the centre of the bar's 12 triangles.
        const size_t first = 2 + (i - 2) / 12 * 12;
        glm::dvec3 centre(0.0);
        for (size_t k = first; k < first + 12; ++k)
            for (const auto& v : s.triangles[k].v) centre += glm::dvec3(v) / 36.0;
        const glm::dvec3 a(t.v[0]), b(t.v[1]), c(t.v[2]);
        CHECK(glm::dot(glm::cross(b - a, c - a), (a + b + c) / 3.0 - centre) > 0);
    }
    StreamSummary flat = summarise(*openEntry({{"type", "grid"}, {"cells", 3}, {"levels", 1}, {"thickness", 0}}), true);
    for (const Triangle& t : flat.triangles) CHECK((t.flags & kTriangleClosed) == 0);
}

TEST_CASE("grid: bad parameters give an error naming the key", "[procedural]") {
    requireInputError({{"type", "grid"}, {"cells", 0}}, "scene.json: geometry[0].cells: must be in 1..4096");
    requireInputError({{"type", "grid"}, {"levels", -1}}, "geometry[0].levels: must be in 0..1024");
    requireInputError({{"type", "grid"}, {"bar", 1.5}}, "geometry[0].bar: must be in (0, 1)");
    requireInputError({{"type", "grid"}, {"size", 0}}, "geometry[0].size: must be in (0, 1e9]");
    requireInputError({{"type", "grid"}, {"holes", 3}}, "geometry[0].holes: unknown key");
}
