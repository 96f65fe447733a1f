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

TEST_CASE("grid: bad parameters give an error naming the key", "[procedural]") {
    requireInputError({{"type", "grid"}, {"cells", 0}}, "scene.json: geometry[0].cells: must be in 1..4096");
    requireInputError({{"type", "grid"}, {"levels", -1}}, "geometry[0].levels: must be in 0..1024");
    requireInputError({{"type", "grid"}, {"bar", 1.5}}, "geometry[0].bar: must be in (0, 1)");
    requireInputError({{"type", "grid"}, {"size", 0}}, "geometry[0].size: must be positive");
    requireInputError({{"type", "grid"}, {"holes", 3}}, "geometry[0].holes: unknown key");
}
