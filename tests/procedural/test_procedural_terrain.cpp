// "terrain" and the noise under it: deterministic streams, a grid of the requested size with
// upward normals inside the stated bounds, terrainHeight() lying exactly on the emitted
// triangles, and clean errors for bad parameters.

#include "ProceduralTestUtil.h"

#include "procedural/Noise.h"
#include "procedural/TerrainGenerator.h"
#include "stream/util/Random.h"

using namespace penumbra;
using namespace penumbra::test;

namespace {

const nlohmann::json kTerrain = {{"type", "terrain"}, {"area", {{-3, -2}, {5, 4}}}, {"resolution", {40, 30}},
                                 {"amplitude", 0.8}, {"octaves", 4}, {"frequency", 0.3}, {"base_height", 0.5}, {"seed", 9}};

TerrainParams paramsOf(const nlohmann::json& entry) {
    nlohmann::json params = entry;
    params.erase("type");
    return parseTerrainParams(SourceRequest{params, "scene.json", "geometry[0]", "."});
}

/// Height of the emitted triangle under (x, z), found by brute force, or NaN when none covers it.
double heightOnTriangles(const std::vector<Triangle>& tris, double x, double z) {
    for (const Triangle& t : tris) {
        const glm::dvec3 a(t.v[0]), b(t.v[1]), c(t.v[2]);
        const double det = (b.x - a.x) * (c.z - a.z) - (c.x - a.x) * (b.z - a.z);
        const double u = ((x - a.x) * (c.z - a.z) - (c.x - a.x) * (z - a.z)) / det;
        const double v = ((b.x - a.x) * (z - a.z) - (x - a.x) * (b.z - a.z)) / det;
        if (u >= -1e-9 && v >= -1e-9 && u + v <= 1 + 1e-9) return a.y + u * (b.y - a.y) + v * (c.y - a.y);
    }
    return std::nan("");
}

}  // namespace

TEST_CASE("gradient noise and fBm are deterministic, bounded and seed-dependent", "[procedural]") {
    FbmParams p;
    p.octaves = 6, p.frequency = 0.7;
    Rng rng(3);
    double lo = 1, hi = -1;
    int differ = 0;
    for (int i = 0; i < 20000; ++i) {
        const double x = rng.uniform(-50, 50), y = rng.uniform(-50, 50);
        const double n = gradientNoise(5, x, y), f = fbm(5, p, x, y);
        CHECK(n >= -1.0);
        CHECK(n <= 1.0);
        REQUIRE(f >= -1.0);
        REQUIRE(f <= 1.0);
        REQUIRE(f == Fbm(5, p)(x, y));  // the cached form gives the same bits
        REQUIRE(gradientNoise(5, x, y) == n);
        differ += fbm(6, p, x, y) != f;
        lo = std::min(lo, f), hi = std::max(hi, f);
        // Continuity: a tiny step changes the value only a little.
        CHECK(std::abs(fbm(5, p, x + 1e-7, y) - f) < 1e-4);
    }
    CHECK(differ > 19000);
    CHECK(hi - lo > 0.8);  // the field actually varies
    CHECK(gradientNoise(1, 3.0, -4.0) == 0.0);  // zero at lattice points, as gradient noise is
    // Far from the origin it stays finite and bounded.
    CHECK(std::abs(fbm(1, p, 1e12, -1e12)) <= 1.0);
}

TEST_CASE("terrain: deterministic for any thread count and chunking", "[procedural]") {
    requireDeterministic(kTerrain);
    nlohmann::json big = kTerrain;
    big["resolution"] = 2100;  // more vertices than the height cache holds: evaluated on demand
    big["area"] = {{0, 0}, {10, 10}};
    TerrainParams p = paramsOf(big);
    REQUIRE(uint64_t(p.cellsX + 1) * (p.cellsZ + 1) > TerrainField::kCachedVertices);
    TerrainField onDemand(p);
    for (int i : {0, 1, 777, 2100})
        for (int k : {0, 5, 2099, 2100}) CHECK(onDemand.vertexHeight(i, k) == terrainVertexHeight(p, i, k));
}

TEST_CASE("terrain: requested grid, finite, upward, inside the stated bounds", "[procedural]") {
    TriangleSourcePtr source = openEntry(kTerrain);
    REQUIRE(source->sizeHint() == 2u * 40 * 30);
    StreamSummary s = summarise(*source, true);
    CHECK(s.count == 2u * 40 * 30);
    CHECK(s.nonFinite == 0);
    CHECK(s.degenerate == 0);
    CHECK(s.flagged == 0);
    CHECK(s.lo.x == -3.0);
    CHECK(s.hi.x == 5.0);
    CHECK(s.lo.z == -2.0);
    CHECK(s.hi.z == 4.0);
    CHECK(s.lo.y >= 0.5 - 0.8);
    CHECK(s.hi.y <= 0.5 + 0.8);
    CHECK(s.hi.y - s.lo.y > 0.2);  // not flat
    for (const Triangle& t : s.triangles) REQUIRE(glm::cross(t.v[1] - t.v[0], t.v[2] - t.v[0]).y > 0);

    // Neighbouring triangles share vertices exactly: no cracks.
    TerrainParams p = paramsOf(kTerrain);
    CHECK(s.triangles[0].v[0] == glm::vec3(-3.0f, terrainVertexHeight(p, 0, 0), -2.0f));
}

TEST_CASE("terrain: terrainHeight() lies on the emitted triangles", "[procedural]") {
    TriangleSourcePtr source = openEntry(kTerrain);
    std::vector<Triangle> tris = readAll(*source);
    TerrainParams p = paramsOf(kTerrain);
    TerrainField field(p);
    Rng rng(11);
    for (int i = 0; i < 300; ++i) {
        const double x = rng.uniform(-3, 5), z = rng.uniform(-2, 4);
        const double h = terrainHeight(p, x, z);
        REQUIRE(field.height(x, z) == h);  // cached and computed paths agree bit for bit
        const double onMesh = heightOnTriangles(tris, x, z);
        REQUIRE(std::isfinite(onMesh));
        CHECK(std::abs(h - onMesh) < 1e-5);
    }
    // Grid vertices themselves, including the far corner.
    CHECK(terrainHeight(p, 5.0, 4.0) == double(terrainVertexHeight(p, 40, 30)));
    CHECK(terrainHeight(p, -3.0, -2.0) == double(terrainVertexHeight(p, 0, 0)));
}

TEST_CASE("terrain: a single resolution number and defaults work, and bad parameters are named", "[procedural]") {
    TriangleSourcePtr source = openEntry({{"type", "terrain"}, {"resolution", 8}});
    CHECK(source->sizeHint() == 2u * 8 * 8);
    CHECK(openEntry({{"type", "terrain"}})->sizeHint() == 2u * 64 * 64);
    CHECK(openEntry({{"type", "terrain"}, {"amplitude", 0}})->sizeHint() == 2u * 64 * 64);  // flat is fine

    auto with = [](const char* key, nlohmann::json value) {
        nlohmann::json e = kTerrain;
        e[key] = value;
        return e;
    };
    requireInputError(with("resolution", 0), "scene.json: geometry[0].resolution: must be in 1..65536, got 0");
    requireInputError(with("resolution", {10, -1}), "geometry[0].resolution: cell counts must be integers");
    requireInputError(with("resolution", {10, 2.5}), "geometry[0].resolution");
    requireInputError(with("area", {{1, 0}, {1, 5}}), "geometry[0].area: area is empty");
    requireInputError(with("area", {{0, 0}, {1}}), "geometry[0].area: expected [[x0, z0], [x1, z1]]");
    requireInputError(with("area", {{0, 0}, {1e12, 1}}), "geometry[0].area: coordinates must be finite");
    requireInputError(with("octaves", 0), "geometry[0].octaves: must be in 1..16");
    requireInputError(with("frequency", -1), "geometry[0].frequency");
    requireInputError(with("amplitude", -0.5), "geometry[0].amplitude");
    requireInputError(with("seed", -3), "geometry[0].seed");
    requireInputError(with("colour", 1), "geometry[0].colour: unknown key");
    requireInputError({{"type", "terrian"}}, "geometry[0]: unknown geometry type \"terrian\"");
    nlohmann::json far = with("area", {{1e8, 0}, {1e8 + 10, 10}});
    far["resolution"] = 65536;
    requireInputError(far, "geometry[0].resolution: cells of 0.000152588 are too small 1e+08 from the origin, where float "
                           "coordinates are 8 apart: a cell needs at least 8 of those steps (64)");
    // A 2 m grid a million units out (floats 0.0625 apart there) is 32 steps a cell: it was
    // refused, and with it 10 m elevation grids in map coordinates.
    nlohmann::json map = with("area", {{999998, 999998}, {1000002, 1000002}});
    map["resolution"] = 2;
    CHECK(openEntry(map)->sizeHint() == 8u);
}
