// "flowers": deterministic, the predicted count per flower, heads at the stem's height, on the
// ground, exact under penumbra casting, and clean errors for bad parameters.

#include "ProceduralBake.h"
#include "ProceduralTestUtil.h"

#include "procedural/FlowerGenerator.h"
#include "stream/AlphaTable.h"

using namespace penumbra;
using namespace penumbra::test;

namespace {

nlohmann::json flowers(nlohmann::json extra = nlohmann::json::object()) {
    nlohmann::json e = {{"type", "flowers"}, {"count", 500}, {"area", {{-2, -1}, {2, 1}}}, {"seed", 3}};
    e.merge_patch(extra);
    return e;
}

FlowerParams paramsOf(const nlohmann::json& entry) {
    nlohmann::json params = entry;
    params.erase("type");
    return parseFlowerParams(SourceRequest{params, "scene.json", "geometry[0]", "."});
}

}  // namespace

TEST_CASE("flowers: deterministic for any thread count and chunking", "[procedural]") {
    requireDeterministic(flowers());
    requireDeterministic(flowers({{"petals", 9}, {"leaves", 0}, {"stem_sides", 5}, {"stem_segments", 3}}));
    requireDeterministic(flowers({{"terrain", {{"area", {{-3, -3}, {3, 3}}}, {"resolution", 9}}}}));
}

TEST_CASE("flowers: predicted count, finite, non-degenerate, within bounds", "[procedural]") {
    nlohmann::json e = flowers({{"base_height", 1.0}, {"height", {0.3, 0.5}}, {"stem_bend", {0, 0.1}}});
    FlowerParams p = paramsOf(e);
    const uint32_t per = flowerTriangleCount(p);
    CHECK(per == 2 * 3 * 2 + 2 * 6 + 3 * 2);  // defaults: 3-sided stem in 2 sections, 6 petals, 2 leaves
    TriangleSourcePtr source = openEntry(e);
    REQUIRE(source->sizeHint() == 500u * per);
    StreamSummary s = summarise(*source, true);
    CHECK(s.count == 500u * per);
    CHECK(s.nonFinite == 0);
    CHECK(s.degenerate == 0);
    CHECK(s.flagged == 500u * 2 * 6);  // the petals, cut out along the petal outline
    for (const Triangle& t : s.triangles)
        CHECK((alphaIdOf(t.flags) == 0 || alphaIdOf(t.flags) == kAlphaPetalLower || alphaIdOf(t.flags) == kAlphaPetalUpper));
    nlohmann::json solid = e;
    solid["petal_cutout"] = false;
    CHECK(summarise(*openEntry(solid)).flagged == 0);
    // Stems root on the plane; heads at most height + a tilted petal above it.
    CHECK(s.lo.y >= 1.0 - 1e-6);
    CHECK(s.hi.y <= 1.0 + 0.5 + 0.06 * std::sin(40 * 3.14159265 / 180) + 1e-5);
    const double reach = 0.5 * 0.1 + 0.06 + 0.006;
    CHECK(s.lo.x >= -2 - reach);
    CHECK(s.hi.x <= 2 + reach);
    CHECK(s.lo.z >= -1 - reach);
    CHECK(s.hi.z <= 1 + reach);
    // The first stem triangle of every flower starts on the ground.
    for (uint64_t f = 0; f < 500; ++f) CHECK(s.triangles[f * per].v[0].y == 1.0f);

    nlohmann::json matte = e;
    matte["alpha_matte"] = true;
    CHECK(summarise(*openEntry(matte)).flagged == 500u * per);
    CHECK(openEntry(flowers({{"count", nullptr}, {"density", 10}}))->sizeHint() == 80u * per);
}

TEST_CASE("a bed of flowers matches the reference caster bit for bit", "[procedural][exact]") {
    std::vector<Triangle> bed = readAll(*openEntry(flowers({{"count", 40}, {"area", {{-0.5, -0.5}, {0.5, 0.5}}},
                                                            {"petal_length", {0.08, 0.15}}, {"leaf_width", 0.04}})));
    std::vector<Triangle> floor;
    addQuad(floor, {-1, 0, -1}, {1, 0, -1}, {1, 0, 1}, {-1, 0, 1});
    ReceiverSet receivers;
    addReceiversOnTriangles(receivers, floor, 41, 150);
    addReceiversOnEvery(receivers, bed, 8, 1, 42);
    bed.insert(bed.end(), floor.begin(), floor.end());
    requireMatchesReference("flowers", {rectLight({0.1, 2, 0}, {0.5, 0, 0}, {0, 0, 0.5}, 64, 4)}, receivers, bed);
}

TEST_CASE("flowers: bad parameters give an error naming the key", "[procedural]") {
    requireInputError(flowers({{"count", -2}}), "scene.json: geometry[0].count: must be in 0..");
    requireInputError(flowers({{"area", {{0, 0}, {0, 0}}}}), "geometry[0].area: area is empty");
    requireInputError(flowers({{"petals", 2}}), "geometry[0].petals: must be in 3..16");
    requireInputError(flowers({{"leaves", 7}}), "geometry[0].leaves: must be in 0..6");
    requireInputError(flowers({{"height", {-1, 1}}}), "geometry[0].height: must lie in (0");
    requireInputError(flowers({{"stem_radius", 0}}), "geometry[0].stem_radius");
    requireInputError(flowers({{"petal_tilt_deg", {0, 95}}}), "geometry[0].petal_tilt_deg");
    requireInputError(flowers({{"petal_width", -1}}), "geometry[0].petal_width");
    requireInputError(flowers({{"colour", "red"}}), "geometry[0].colour: unknown key");
}
