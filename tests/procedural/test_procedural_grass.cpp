// "grass": deterministic, exactly the requested number of blades of the requested shape, rooted
// on the ground (plane or terrain), thinned into clumps without changing the count, a billion
// blades expressible, exact under penumbra casting, and clean errors for bad parameters.

#include "ProceduralBake.h"
#include "ProceduralTestUtil.h"

#include "procedural/GrassGenerator.h"
#include "procedural/Noise.h"

using namespace penumbra;
using namespace penumbra::test;

namespace {

const nlohmann::json kTerrain = {{"area", {{-2, -2}, {2, 2}}}, {"resolution", 12}, {"amplitude", 0.3}, {"octaves", 3},
                                 {"frequency", 0.4}, {"seed", 4}};

nlohmann::json grass(nlohmann::json extra = nlohmann::json::object()) {
    nlohmann::json e = {{"type", "grass"}, {"count", 2000}, {"area", {{-1, -1}, {3, 2}}}, {"height", {0.2, 0.5}},
                        {"width", {0.01, 0.03}}, {"bend", {0.1, 0.4}}, {"seed", 7}};
    e.merge_patch(extra);
    return e;
}

GrassParams paramsOf(const nlohmann::json& entry) {
    nlohmann::json params = entry;
    params.erase("type");
    return parseGrassParams(SourceRequest{params, "scene.json", "geometry[0]", "."});
}

}  // namespace

TEST_CASE("grass: deterministic for any thread count and chunking", "[procedural]") {
    requireDeterministic(grass());
    requireDeterministic(grass({{"segments", 4}, {"alpha_matte", true}}));
    requireDeterministic(grass({{"terrain", kTerrain}, {"area", nullptr}, {"clump", {{"frequency", 0.8}}}}));
    CHECK(hashWithThreads(grass(), 2) != hashWithThreads(grass({{"seed", 8}}), 2));
}

TEST_CASE("grass: every segment count gives count x segments sane triangles within bounds", "[procedural]") {
    for (int segments = 3; segments <= 7; ++segments) {
        INFO("segments " << segments);
        nlohmann::json e = grass({{"segments", segments}, {"base_height", 0.25}});
        TriangleSourcePtr source = openEntry(e);
        REQUIRE(source->sizeHint() == 2000u * segments);
        StreamSummary s = summarise(*source, true);
        CHECK(s.count == 2000u * segments);
        CHECK(s.nonFinite == 0);
        CHECK(s.degenerate == 0);
        CHECK(s.flagged == 0);
        // Roots inside the area; tips at most the tallest blade above the ground, bent at most
        // bend x height, plus half a width, sideways.
        const double reach = 0.4 * 0.5 + 0.015 + 1e-6;
        CHECK(s.lo.x >= -1 - reach);
        CHECK(s.hi.x <= 3 + reach);
        CHECK(s.lo.z >= -1 - reach);
        CHECK(s.hi.z <= 2 + reach);
        CHECK(s.lo.y == Approx(0.25).margin(1e-7));
        CHECK(s.hi.y <= 0.25 + 0.5 + 1e-6);
        CHECK(s.hi.y > 0.25 + 0.45);  // some blade is nearly as tall as allowed
        // Blade shape: first two vertices are the root edge on the ground, the last is the tip.
        for (size_t b = 0; b < 2000; b += 97) {
            const Triangle& first = s.triangles[b * segments];
            const Triangle& last = s.triangles[b * segments + segments - 1];
            CHECK(first.v[0].y == first.v[1].y);
            const double width = glm::length(glm::dvec3(first.v[0]) - glm::dvec3(first.v[1]));
            CHECK(width >= 0.01 - 1e-6);
            CHECK(width <= 0.03 + 1e-6);
            const double height = double(last.v[2].y) - 0.25;
            CHECK(height >= 0.2 - 1e-6);
            CHECK(height <= 0.5 + 1e-6);
        }
    }
}

TEST_CASE("grass: stratified placement covers the area evenly", "[procedural]") {
    // 6400 blades over 8 x 8: 10 x 10 tiles of 64 blades, so every 1.6 x 1.6 square (2 x 2 tiles) gets 256.
    nlohmann::json e = grass({{"count", 6400}, {"area", {{0, 0}, {8, 8}}}});
    GrassParams p = paramsOf(e);
    int cells[5][5] = {};
    for (uint64_t b = 0; b < 6400; ++b) {
        const glm::dvec3 r = grassBladeRoot(p, b);
        REQUIRE(r.x >= 0);
        REQUIRE(r.x < 8);
        REQUIRE(r.z >= 0);
        REQUIRE(r.z < 8);
        ++cells[int(r.x / 1.6)][int(r.z / 1.6)];
    }
    for (auto& row : cells)
        for (int n : row) CHECK(n == 256);
    // Consecutive blades stay close together (one tile is 0.8 x 0.8).
    for (uint64_t b = 0; b + 1 < 6400; b += 64) {
        const glm::dvec3 a = grassBladeRoot(p, b), c = grassBladeRoot(p, b + 63);
        CHECK(glm::length(a - c) < 0.8 * std::sqrt(2.0));
    }
}

TEST_CASE("grass: blades stand on the terrain's triangulated surface", "[procedural]") {
    nlohmann::json e = grass({{"terrain", kTerrain}, {"area", {{-1.5, -1.9}, {2, 1}}}, {"count", 3000}});
    GrassParams p = paramsOf(e);
    REQUIRE(p.placement.terrain);
    std::vector<Triangle> tris = readAll(*openEntry(e));
    REQUIRE(tris.size() == 3000u * 5);
    for (uint64_t b = 0; b < 3000; ++b) {
        const Triangle& t = tris[b * 5];
        const glm::dvec3 root = 0.5 * (glm::dvec3(t.v[0]) + glm::dvec3(t.v[1]));
        const glm::dvec3 expected = grassBladeRoot(p, b);
        REQUIRE(std::abs(root.x - expected.x) < 1e-5);
        REQUIRE(std::abs(root.z - expected.z) < 1e-5);
        CHECK(root.x >= -1.5);
        CHECK(root.x <= 2.0);
        // On the triangulated heightfield (not the raw noise), to float precision.
        REQUIRE(std::abs(root.y - terrainHeight(p.placement.terrain->params(), root.x, root.z)) < 2e-6);
    }
}

TEST_CASE("grass: the clump mask makes bare patches but keeps the count exact", "[procedural]") {
    nlohmann::json e = grass({{"count", 4000}, {"area", {{0, 0}, {10, 10}}},
                              {"clump", {{"frequency", 0.3}, {"threshold", 0.05}, {"tries", 8}}}});
    GrassParams p = paramsOf(e);
    REQUIRE(p.clump.enabled);
    TriangleSourcePtr source = openEntry(e);
    CHECK(source->sizeHint() == 4000u * 5);
    StreamSummary s = summarise(*source);
    CHECK(s.count == 4000u * 5);
    CHECK(s.degenerate == 0);
    CHECK(s.nonFinite == 0);

    Fbm mask(p.clump.seed, p.clump.noise);
    Rng rng(5);
    int bareArea = 0;
    for (int i = 0; i < 4000; ++i) bareArea += mask(rng.uniform(0, 10), rng.uniform(0, 10)) < p.clump.threshold;
    int bareBlades = 0;
    for (uint64_t b = 0; b < 4000; ++b) {
        glm::dvec3 r = grassBladeRoot(p, b);
        bareBlades += mask(r.x, r.z) < p.clump.threshold;
    }
    INFO("bare area " << bareArea / 40.0 << "%, bare blades " << bareBlades);
    // A good part of the area is bare, yet only the documented stragglers stand there: a blade
    // ends up bare when all its tries land bare, with probability bare^tries.
    const double bare = bareArea / 4000.0, expected = std::pow(bare, p.clump.tries);
    CHECK(bare > 0.3);
    CHECK(bareBlades / 4000.0 < 1.5 * expected + 0.005);
    CHECK(bareBlades / 4000.0 < 0.1 * bare);
    CHECK(hashWithThreads(e, 1) != hashWithThreads(grass({{"count", 4000}, {"area", {{0, 0}, {10, 10}}}}), 1));
}

TEST_CASE("grass: density, a billion blades, and empty fields", "[procedural]") {
    // Density is per square unit of the area, rounded: 4 x 3 x 250.4 = 3004.8 -> 3005 blades.
    CHECK(openEntry(grass({{"count", nullptr}, {"density", 250.4}}))->sizeHint() == 3005u * 5);
    // A billion blades are expressible and stream without being stored.
    TriangleSourcePtr huge = openEntry(grass({{"count", 1000000000}, {"segments", 7}}));
    CHECK(huge->sizeHint() == 7000000000u);
    std::vector<Triangle> chunk(kTriangleChunk);
    CHECK(huge->read(chunk) == kTriangleChunk);
    CHECK(isFinite(chunk.back()));
    // Zero blades is a valid, empty stream.
    TriangleSourcePtr none = openEntry(grass({{"count", 0}}));
    CHECK(none->sizeHint() == 0u);
    CHECK(none->read(chunk) == 0);
}

TEST_CASE("grass on terrain with clumps matches the reference caster bit for bit", "[procedural][exact]") {
    nlohmann::json terrain = kTerrain;
    terrain["area"] = {{-1, -1}, {1, 1}};
    terrain["resolution"] = 6;
    terrain["amplitude"] = 0.1;
    nlohmann::json terrainEntry = terrain;
    terrainEntry["type"] = "terrain";
    std::vector<Triangle> ground = readAll(*openEntry(terrainEntry));
    std::vector<Triangle> blades = readAll(*openEntry(grass(
        {{"count", 200}, {"terrain", terrain}, {"area", nullptr}, {"height", {0.1, 0.3}}, {"width", {0.02, 0.05}},
         {"clump", {{"frequency", 1.0}, {"threshold", -0.2}}}})));
    ReceiverSet receivers;
    addReceiversOnEvery(receivers, ground, 1, 4, 21);
    addReceiversOnEvery(receivers, blades, 10, 1, 22);
    std::vector<Triangle> all = blades;
    all.insert(all.end(), ground.begin(), ground.end());
    requireMatchesReference("grass on terrain", {rectLight({0.2, 2.5, 0.1}, {0.8, 0, 0}, {0, 0, 0.8}, 64, 4)}, receivers, all);
}

TEST_CASE("grass: bad parameters give an error naming the key", "[procedural]") {
    requireInputError(grass({{"count", -5}}), "scene.json: geometry[0].count: must be in 0..");
    requireInputError(grass({{"count", 1.5}}), "geometry[0].count: expected an integer");
    requireInputError(grass({{"density", -1}, {"count", nullptr}}), "geometry[0].density: must not be negative");
    requireInputError(grass({{"density", 1e30}, {"count", nullptr}}), "geometry[0].density: gives");
    requireInputError(grass({{"density", 5}}), "geometry[0].density: give either \"count\" or \"density\"");
    requireInputError(grass({{"area", {{0, 0}, {0, 1}}}}), "geometry[0].area: area is empty");
    requireInputError(grass({{"area", {{2, 0}, {1, 1}}}}), "geometry[0].area: area is empty");
    requireInputError(grass({{"segments", 8}}), "geometry[0].segments: must be in 3..7");
    requireInputError(grass({{"segments", 2}}), "geometry[0].segments: must be in 3..7");
    requireInputError(grass({{"height", {0, 0.5}}}), "geometry[0].height: must lie in (0");
    requireInputError(grass({{"height", {0.5, 0.2}}}), "geometry[0].height: range is empty");
    requireInputError(grass({{"width", -0.01}}), "geometry[0].width");
    requireInputError(grass({{"clump", {{"threshold", 2}}}}), "geometry[0].clump.threshold: must be in [-1, 1]");
    requireInputError(grass({{"clump", {{"sharpness", 2}}}}), "geometry[0].clump.sharpness: unknown key");
    requireInputError(grass({{"terrain", kTerrain}, {"area", {{-3, 0}, {1, 1}}}}), "geometry[0].area: must lie inside the terrain's area");
    requireInputError(grass({{"terrain", {{"octaves", 0}}}}), "geometry[0].terrain.octaves: must be in 1..16");
    requireInputError(grass({{"terrain", kTerrain}, {"base_height", 1}}), "geometry[0].base_height: cannot be combined");
    requireInputError(grass({{"heigth", 0.3}}), "geometry[0].heigth: unknown key");
    requireInputError({{"type", "grasss"}}, "scene.json: geometry[0]: unknown geometry type \"grasss\" (known: ");
}
