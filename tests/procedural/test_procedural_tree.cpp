// "tree" and "forest": deterministic, the predicted triangle count with alpha-matte leaves,
// within the reach the parameters allow, forests standing on their terrain, exact under
// penumbra casting, and clean errors for bad parameters.

#include "ProceduralBake.h"
#include "ProceduralTestUtil.h"

#include "procedural/TreeGenerator.h"

using namespace penumbra;
using namespace penumbra::test;

namespace {

const nlohmann::json kTerrain = {{"area", {{-20, -20}, {20, 20}}}, {"resolution", 16}, {"amplitude", 1.5}, {"octaves", 3},
                                 {"frequency", 0.05}, {"seed", 2}};

template <typename Params, typename Parse>
Params parse(const nlohmann::json& entry, Parse parser) {
    nlohmann::json params = entry;
    params.erase("type");
    return parser(SourceRequest{params, "scene.json", "geometry[0]", "."});
}

}  // namespace

TEST_CASE("tree and forest: deterministic for any thread count and chunking", "[procedural]") {
    requireDeterministic({{"type", "tree"}});
    requireDeterministic({{"type", "tree"}, {"depth", 3}, {"branches", 4}, {"jitter", 0.8}, {"seed", 5}});
    requireDeterministic({{"type", "forest"}, {"count", 30}, {"depth", 3}, {"area", {{0, 0}, {30, 20}}}});
    requireDeterministic({{"type", "forest"}, {"count", 25}, {"depth", 2}, {"terrain", kTerrain}, {"variants", 3}});
    CHECK(hashWithThreads({{"type", "tree"}, {"seed", 1}}, 2) != hashWithThreads({{"type", "tree"}, {"seed", 2}}, 2));
}

TEST_CASE("tree: predicted count, alpha-matte leaves, trunk at the origin, within reach", "[procedural]") {
    nlohmann::json e = {{"type", "tree"}, {"depth", 4}, {"branches", 3}, {"sides", 6}, {"leaves_per_branch", 8}};
    TreeParams p = parse<TreeParams>(e, parseTreeParams);
    // 1 + 3 + 9 + 27 + 81 branches of 12 triangles, 81 outermost branches with 8 two-triangle leaves.
    CHECK(treeTriangleCount(p) == 121u * 12 + 81u * 8 * 2);
    TriangleSourcePtr source = openEntry(e);
    REQUIRE(source->sizeHint() == treeTriangleCount(p));
    StreamSummary s = summarise(*source, true);
    CHECK(s.count == treeTriangleCount(p));
    CHECK(s.nonFinite == 0);
    CHECK(s.degenerate == 0);
    CHECK(s.flagged == 81u * 8 * 2);  // exactly the leaves
    for (size_t i = 0; i < s.triangles.size(); ++i) CHECK(bool(s.triangles[i].flags & kTriangleAlphaMatte) == (i >= 121u * 12));

    const double reach = treeReach(p);
    for (const Triangle& t : s.triangles)
        for (const glm::vec3& v : t.v) REQUIRE(glm::length(glm::dvec3(v)) <= reach + 1e-5);
    CHECK(s.hi.y > 0.5 * p.trunkLength * 2);  // it does grow up and out
    CHECK(s.lo.y >= -1e-6);
    // The trunk's base ring lies at y = 0 around the origin with the trunk radius.
    for (int k = 0; k < p.sides; ++k) {
        const Triangle& t = s.triangles[2 * k];
        CHECK(t.v[0].y == 0.0f);
        CHECK(glm::length(glm::dvec3(t.v[0])) == Approx(p.trunkRadius).epsilon(1e-5));
    }

    nlohmann::json opaque = e;
    opaque["alpha_matte"] = false;
    CHECK(summarise(*openEntry(opaque)).flagged == 0);
    // A bare trunk and a leafless tree are allowed.
    CHECK(openEntry({{"type", "tree"}, {"depth", 0}, {"sides", 5}})->sizeHint() == 10u + 8u * 2);
    CHECK(openEntry({{"type", "tree"}, {"leaves_per_branch", 0}, {"depth", 1}, {"branches", 2}})->sizeHint() == 3u * 12);
}

TEST_CASE("forest: count x tree triangles, trees inside the area and standing on the terrain", "[procedural]") {
    nlohmann::json e = {{"type", "forest"}, {"count", 40}, {"depth", 2}, {"terrain", kTerrain},
                        {"area", {{-15, -10}, {15, 18}}}, {"scale", {0.7, 1.3}}, {"seed", 12}};
    ForestParams f = parse<ForestParams>(e, parseForestParams);
    const uint64_t per = treeTriangleCount(f.tree);
    TriangleSourcePtr source = openEntry(e);
    REQUIRE(source->sizeHint() == 40 * per);
    StreamSummary s = summarise(*source, true);
    CHECK(s.count == 40 * per);
    CHECK(s.nonFinite == 0);
    CHECK(s.degenerate == 0);
    CHECK(s.flagged == 40 * (per - (1 + 3 + 9) * 12));
    const double reach = treeReach(f.tree) * 1.3;
    CHECK(s.lo.x >= -15 - reach);
    CHECK(s.hi.x <= 15 + reach);
    CHECK(s.lo.z >= -10 - reach);
    CHECK(s.hi.z <= 18 + reach);
    for (uint64_t t = 0; t < 40; ++t) {
        // Centre of the trunk's base ring (the first vertex of its first `sides` triangles).
        glm::dvec3 centre(0.0);
        for (int k = 0; k < f.tree.sides; ++k) centre += glm::dvec3(s.triangles[t * per + 2 * k].v[0]);
        centre /= double(f.tree.sides);
        CHECK(centre.x >= -15);
        CHECK(centre.x <= 15);
        CHECK(centre.z >= -10);
        CHECK(centre.z <= 18);
        // Sunk by trunk_radius x scale (scale in [0.7, 1.3]) below the terrain's surface.
        const double ground = terrainHeight(f.placement.terrain->params(), centre.x, centre.z);
        CHECK(centre.y <= ground - 0.7 * f.tree.trunkRadius + 1e-4);
        CHECK(centre.y >= ground - 1.3 * f.tree.trunkRadius - 1e-4);
    }
}

TEST_CASE("a small tree with leaves over a floor matches the reference caster bit for bit", "[procedural][exact]") {
    std::vector<Triangle> tree = readAll(*openEntry({{"type", "tree"}, {"depth", 2}, {"branches", 3}, {"sides", 5},
                                                     {"leaves_per_branch", 4}, {"leaf_size", 0.3}, {"trunk_length", 1.0}}));
    std::vector<Triangle> floor;
    addQuad(floor, {-2, 0, -2}, {2, 0, -2}, {2, 0, 2}, {-2, 0, 2});
    ReceiverSet receivers;
    addReceiversOnTriangles(receivers, floor, 31, 250);
    addReceiversOnEvery(receivers, tree, 3, 1, 32);
    tree.insert(tree.end(), floor.begin(), floor.end());
    requireMatchesReference("tree", {rectLight({0.3, 4, 0.2}, {1.0, 0, 0}, {0, 0, 1.0}, 64, 4)}, receivers, tree);
}

TEST_CASE("tree and forest: bad parameters give an error naming the key", "[procedural]") {
    requireInputError({{"type", "tree"}, {"depth", 13}}, "scene.json: geometry[0].depth: must be in 0..12, got 13");
    requireInputError({{"type", "tree"}, {"depth", 12}, {"branches", 8}}, "geometry[0].depth: a tree would have");
    requireInputError({{"type", "tree"}, {"branches", 0}}, "geometry[0].branches: must be in 1..8");
    requireInputError({{"type", "tree"}, {"radius_ratio", 0}}, "geometry[0].radius_ratio: must be in (0, 1]");
    requireInputError({{"type", "tree"}, {"length_ratio", -1}}, "geometry[0].length_ratio");
    requireInputError({{"type", "tree"}, {"branching_angle_deg", 200}}, "geometry[0].branching_angle_deg");
    requireInputError({{"type", "tree"}, {"sides", 2}}, "geometry[0].sides: must be in 3..32");
    requireInputError({{"type", "tree"}, {"leaf_size", 0}}, "geometry[0].leaf_size");
    requireInputError({{"type", "tree"}, {"jitter", 1.5}}, "geometry[0].jitter");
    requireInputError({{"type", "tree"}, {"count", 3}}, "geometry[0].count: unknown key");  // a tree is one tree
    requireInputError({{"type", "forest"}, {"count", -1}}, "geometry[0].count: must be in 0..");
    requireInputError({{"type", "forest"}, {"area", {{0, 0}, {-1, 1}}}}, "geometry[0].area: area is empty");
    requireInputError({{"type", "forest"}, {"scale", {0, 1}}}, "geometry[0].scale: must lie in (0, 1000]");
    requireInputError({{"type", "forest"}, {"variants", 0}}, "geometry[0].variants: must be in 1..64");
    requireInputError({{"type", "forest"}, {"terrain", {{"resolution", 0}}}}, "geometry[0].terrain.resolution");
    requireInputError({{"type", "forrest"}}, "geometry[0]: unknown geometry type \"forrest\"");
}
