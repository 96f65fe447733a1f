// Generated lightmap atlases: no two charts share a texel, the gutter keeps each chart's padding
// its own, the atlas is well used on the example and on real meshes, the result does not depend
// on the thread count, and broken input (degenerate triangles, non-manifold edges, surfaces that
// overlap in projection) is cut without crashing. Also the crease-angle shading normals.

#include "AtlasChecks.h"
#include "TestSupport.h"

#include "receivers/ChartConformalMap.h"
#include "receivers/ChartParameterization.h"
#include "receivers/CreaseNormals.h"
#include "receivers/LightmapAtlas.h"
#include "stream/IndexedMesh.h"

#include <catch2/catch.hpp>
#include <glm/geometric.hpp>
#include <tbb/global_control.h>

#include <bit>
#include <cmath>
#include <filesystem>
#include <numbers>

using namespace penumbra;
using namespace penumbra::test;

namespace {

IndexedMesh load(const std::string& path) { return loadIndexedMeshes(path, glm::mat4(1.f)).at(0); }

std::string example(const std::string& name) { return std::string(PENUMBRA_SOURCE_DIR) + "/examples/" + name; }

/// A UV sphere of @p rings x @p segments quads, welded (one vertex per position), no normals.
IndexedMesh sphere(int rings, int segments) {
    IndexedMesh mesh;
    for (int i = 0; i <= rings; ++i)
        for (int j = 0; j < segments; ++j) {
            const double theta = std::numbers::pi * i / rings, phi = 2 * std::numbers::pi * j / segments;
            if ((i == 0 || i == rings) && j > 0) continue;  // one vertex per pole
            mesh.position.emplace_back(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
        }
    auto at = [&](int i, int j) -> uint32_t {
        if (i == 0) return 0;
        if (i == rings) return uint32_t(1 + (rings - 1) * segments);
        return uint32_t(1 + (i - 1) * segments + (j % segments));
    };
    for (int i = 0; i < rings; ++i)
        for (int j = 0; j < segments; ++j) {
            const uint32_t a = at(i, j), b = at(i, j + 1), c = at(i + 1, j), d = at(i + 1, j + 1);
            if (i > 0) mesh.indices.insert(mesh.indices.end(), {a, b, c});  // outward: counter-clockwise seen from outside
            if (i < rings - 1) mesh.indices.insert(mesh.indices.end(), {b, d, c});
        }
    return mesh;
}

/// A unit cube of 12 triangles sharing its 8 corners, outward, no normals.
IndexedMesh cube() {
    IndexedMesh mesh;
    for (int i = 0; i < 8; ++i) mesh.position.emplace_back(i & 1, (i >> 1) & 1, (i >> 2) & 1);
    mesh.indices = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
    return mesh;
}

LightmapAtlas atlasOf(std::vector<IndexedMesh> meshes, int side, int padding) {
    AtlasOptions options;
    options.pack.width = options.pack.height = side;
    options.pack.padding = padding;
    return buildLightmapAtlas(meshes, options);
}

/// The checks every atlas must pass; returns the fraction of the atlas covered.
double requireSound(const LightmapAtlas& atlas, int padding) {
    REQUIRE(atlas.width > 0);
    const AtlasCoverage coverage = checkAtlas(atlas, 2 * padding + 1);
    CHECK(coverage.contested == 0);
    CHECK(coverage.closest >= 2 * padding + 1);  // 2 * padding free texels: dilation rings never meet
    for (const IndexedMesh& mesh : atlas.meshes)
        for (glm::vec2 uv : mesh.uv1) {
            CHECK(uv.x >= 0.0f);
            CHECK(uv.x <= 1.0f);
            CHECK(uv.y >= 0.0f);
            CHECK(uv.y <= 1.0f);
        }
    return coverage.used() / (double(atlas.width) * atlas.height);
}

}  // namespace

TEST_CASE("atlas: the lightmap example's meshes pack into one atlas without overlap, over 60% used", "[atlas]") {
    const int padding = 4;
    LightmapAtlas atlas = atlasOf({load(example("room.obj")), load(example("room-blockers.obj"))}, 512, padding);
    CHECK(atlas.width == 512);
    CHECK(atlas.height == 512);
    const double used = requireSound(atlas, padding);
    WARN("room + blockers at 512, padding 4: " << atlas.charts << " charts, " << atlas.texelsPerUnit
                                               << " texels/unit, " << 100 * used << "% covered");
    CHECK(used >= 0.60);
}

namespace {

/// A real mesh without UVs, alone in a 1024 x 1024 atlas with padding 2: over 60% covered.
void requireWellUsed(const char* name) {
    const int padding = 2;
    LightmapAtlas atlas = atlasOf({load(sharedData(std::string("meshes/") + name))}, 1024, padding);
    const double used = requireSound(atlas, padding);
    WARN(name << " at 1024, padding 2: " << atlas.charts << " charts, " << 100 * used << "% covered");
    CHECK(used >= 0.60);
}

}  // namespace

TEST_CASE("atlas: cow.obj packs over 60% of the atlas", "[atlas]") { requireWellUsed("cow.obj"); }
TEST_CASE("atlas: teapot.obj packs over 60% of the atlas", "[atlas]") { requireWellUsed("teapot.obj"); }
TEST_CASE("atlas: spot.obj packs over 60% of the atlas", "[atlas]") { requireWellUsed("spot.obj"); }

TEST_CASE("atlas: the same UVs for one thread and for two", "[atlas]") {
    std::vector<IndexedMesh> meshes{load(sharedData("meshes/teapot.obj")), load(example("room.obj")), sphere(24, 48)};
    auto build = [&](int threads) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
        return atlasOf(meshes, 1024, 3);
    };
    const LightmapAtlas one = build(1), two = build(2);
    REQUIRE(one.width == two.width);
    CHECK(one.texelsPerUnit == two.texelsPerUnit);
    REQUIRE(one.meshes.size() == two.meshes.size());
    for (size_t m = 0; m < one.meshes.size(); ++m) {
        CHECK(one.meshes[m].uv1 == two.meshes[m].uv1);
        CHECK(one.meshes[m].indices == two.meshes[m].indices);
        CHECK(one.meshes[m].position == two.meshes[m].position);
    }
    requireSound(one, 3);
}

TEST_CASE("atlas: degenerate triangles, fins and duplicate faces are cut without overlap", "[atlas]") {
    IndexedMesh mesh = cube();
    const uint32_t n = uint32_t(mesh.position.size());
    mesh.position.insert(mesh.position.end(), {{0, 0, 2}, {1, 0, 2}, {2, 0, 2}, {0.5f, 1, 2}, {0.5f, -1, 2}, {0.5f, 0, 3}});
    mesh.indices.insert(mesh.indices.end(), {
        n, n + 1, n + 2,      // collinear: zero area
        n, n, n + 3,          // a repeated corner
        n, n + 1, n + 3,      // three faces on edge (n, n+1): a non-manifold fin
        n + 1, n, n + 4,
        n, n + 1, n + 5,
        n, n + 1, n + 3,      // a duplicate face
        0, 2, 1,              // a duplicate of the cube's first face
    });
    for (int padding : {0, 1, 4}) {
        LightmapAtlas atlas = atlasOf({mesh}, 64, padding);
        INFO("padding " << padding);
        requireSound(atlas, padding);
        REQUIRE(atlas.meshes[0].triangleCount() == mesh.triangleCount());
        for (size_t c = 0; c < mesh.indices.size(); ++c)  // split vertices keep their positions
            CHECK(atlas.meshes[0].position[atlas.meshes[0].indices[c]] == mesh.position[mesh.indices[c]]);
    }
    IndexedMesh empty;
    LightmapAtlas none = atlasOf({empty}, 16, 2);
    CHECK(none.charts == 0);
    CHECK(none.meshes.at(0).triangleCount() == 0);
}

TEST_CASE("atlas: a spiral ramp that overlaps itself in projection is split", "[atlas]") {
    // Two turns of a gently sloped ramp: every normal is near +y, but the turns lie above each other.
    IndexedMesh ramp;
    const int steps = 160;
    for (int i = 0; i <= steps; ++i) {
        const double a = 4 * std::numbers::pi * i / steps, y = 0.05 * i / steps * 4;
        for (double r : {1.0, 2.0}) ramp.position.emplace_back(r * std::cos(a), y, -r * std::sin(a));
    }
    for (uint32_t i = 0; i < steps; ++i) {
        const uint32_t a = 2 * i, b = a + 1, c = a + 2, d = a + 3;
        ramp.indices.insert(ramp.indices.end(), {a, c, b, b, c, d});
    }
    ChartLimits limits;
    limits.coneDeg = 30;
    std::vector<Chart> charts = makeCharts(ramp, 0, limits);
    CHECK(charts.size() >= 2);
    size_t triangles = 0;
    for (const Chart& chart : charts) {
        CHECK_FALSE(chartOverlapsItself(chart));
        triangles += chart.triangles.size();
    }
    CHECK(triangles == ramp.triangleCount());
    requireSound(atlasOf({ramp}, 256, 2), 2);
}

TEST_CASE("atlas: at a fixed density the size is the smallest found, powers of two when asked", "[atlas]") {
    std::vector<IndexedMesh> meshes{load(example("room.obj")), load(example("room-blockers.obj"))};
    AtlasOptions options;
    options.pack.texelsPerUnit = 40, options.pack.padding = 2;
    LightmapAtlas tight = buildLightmapAtlas(meshes, options);
    CHECK(tight.texelsPerUnit == 40);
    CHECK_FALSE(tight.densityLowered);
    const double used = requireSound(tight, 2);
    CHECK(used >= 0.6);
    options.pack.powerOfTwo = true;
    LightmapAtlas pow2 = buildLightmapAtlas(meshes, options);
    CHECK(std::has_single_bit(unsigned(pow2.width)));
    CHECK(std::has_single_bit(unsigned(pow2.height)));
    CHECK(int64_t(pow2.width) * pow2.height >= int64_t(tight.width) * tight.height);
    requireSound(pow2, 2);
    // A cap below what the density needs lowers the density to fit the cap.
    options.pack.powerOfTwo = false, options.pack.maxSide = 128;
    LightmapAtlas capped = buildLightmapAtlas(meshes, options);
    CHECK(capped.densityLowered);
    CHECK(capped.width == 128);
    CHECK(capped.texelsPerUnit < 40);
    requireSound(capped, 2);
    // A density no atlas could hold is lowered too, without making masks of its size.
    options.pack.texelsPerUnit = 1e9;
    LightmapAtlas huge = buildLightmapAtlas(meshes, options);
    CHECK(huge.densityLowered);
    requireSound(huge, 2);
}

TEST_CASE("crease normals: a fine sphere shades smoothly, a cube keeps its hard edges", "[atlas][normals]") {
    const IndexedMesh ball = withCreaseNormals(sphere(32, 64), kDefaultCreaseAngleDeg);
    REQUIRE(ball.normal.size() == ball.position.size());
    // Welded and smooth: no vertex split, and every normal is the radial direction.
    CHECK(ball.position.size() == sphere(32, 64).position.size());
    for (size_t v = 0; v < ball.position.size(); ++v) {
        INFO("vertex " << v);
        CHECK(glm::dot(glm::dvec3(ball.normal[v]), glm::normalize(glm::dvec3(ball.position[v]))) > 0.999);
    }
    const IndexedMesh box = withCreaseNormals(cube(), kDefaultCreaseAngleDeg);
    CHECK(box.position.size() == 24);  // each corner once per face around it
    for (size_t c = 0; c < box.indices.size(); ++c) {
        const size_t t = c / 3;
        const glm::vec3 a = box.position[box.indices[3 * t]], b = box.position[box.indices[3 * t + 1]],
                        d = box.position[box.indices[3 * t + 2]];
        CHECK(box.normal[box.indices[c]] == glm::normalize(glm::cross(b - a, d - a)));
    }
    // Past the crease angle the cube is smooth too: one normal per corner, along the diagonal.
    const IndexedMesh round = withCreaseNormals(cube(), 120);
    CHECK(round.position.size() == 8);
    for (size_t v = 0; v < 8; ++v)
        CHECK(glm::dot(glm::dvec3(round.normal[v]), glm::normalize(glm::dvec3(round.position[v]) - 0.5)) > 0.999);
}

TEST_CASE("atlas: every mesh of the shared glTF corpus that loads packs soundly", "[atlas]") {
    size_t packed = 0;
    for (const auto& e : std::filesystem::recursive_directory_iterator(sharedData("gltf"))) {
        const std::string ext = e.path().extension().string();
        if (!e.is_regular_file() || (ext != ".gltf" && ext != ".glb")) continue;
        std::vector<IndexedMesh> meshes;
        try {
            meshes = loadIndexedMeshes(e.path().string(), glm::mat4(1.f));
        } catch (const InputError&) {
            continue;  // malformed on purpose: the loader's tests cover the message
        }
        INFO(e.path().string());
        for (IndexedMesh& mesh : meshes) mesh = withCreaseNormals(mesh, kDefaultCreaseAngleDeg);
        requireSound(atlasOf(meshes, 128, 2), 2);
        ++packed;
    }
    CHECK(packed > 0);
}

TEST_CASE("atlas: a conformal map unrolls a cylinder patch that a projection squeezes", "[atlas]") {
    // A quarter of a cylinder of radius 1 and height 1: developable, so an unrolled chart keeps
    // every length; projected onto its mean plane, its sides shrink by up to cos 45 degrees.
    IndexedMesh patch;
    const int segments = 24;
    for (int i = 0; i <= segments; ++i) {
        const double a = std::numbers::pi / 4 * (2.0 * i / segments - 1);
        for (double y : {0.0, 1.0}) patch.position.emplace_back(std::sin(a), y, std::cos(a));
    }
    for (uint32_t i = 0; i < uint32_t(segments); ++i)
        patch.indices.insert(patch.indices.end(), {2 * i, 2 * i + 2, 2 * i + 1, 2 * i + 1, 2 * i + 2, 2 * i + 3});
    const ChartSurface surface(patch);
    std::vector<uint32_t> all(patch.triangleCount());
    for (uint32_t t = 0; t < all.size(); ++t) all[t] = t;
    Chart chart;
    REQUIRE(projectChart(surface, all, 60, chart));
    CHECK(chart.size.x == Approx(std::sqrt(2.0)).epsilon(1e-6));  // the chord, not the arc
    REQUIRE(conformalMap(surface, chart));
    // Every edge keeps its length (to the chord error of the tessellation), so the unrolled
    // patch is the arc's length long.
    double longest = 0;
    for (size_t t = 0; t < chart.corners.size(); ++t)
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = chart.corners[t][k], b = chart.corners[t][(k + 1) % 3];
            const double flat = glm::length(chart.uv[a] - chart.uv[b]);
            const double surfaceLength = glm::length(glm::dvec3(patch.position[chart.vertices[a]] - patch.position[chart.vertices[b]]));
            CHECK(flat == Approx(surfaceLength).epsilon(1e-3));
            longest = std::max(longest, glm::length(chart.uv[a] - chart.uv[0]));
        }
    CHECK(chart.area == Approx(chart.flatArea));
    CHECK(longest > 1.85);  // the unrolled diagonal: sqrt(1 + (pi / 2)^2) = 1.862, the chord's is 1.732
}
