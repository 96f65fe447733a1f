// "scatter": N placed instances of any source (a file or another generator), the same bytes
// whether the source is kept in memory or re-streamed per instance, placement as documented,
// and clean errors naming the key, including keys of the inline source.

#include "ProceduralTestUtil.h"
#include "TestSupport.h"

#include "bake/Scene.h"
#include "procedural/TerrainGenerator.h"
#include "procedural/TreeGenerator.h"
#include "stream/util/JsonParams.h"

#include <fstream>

using namespace penumbra;
using namespace penumbra::test;

namespace {

void writeText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

nlohmann::json scatterOf(nlohmann::json source, nlohmann::json extra = nlohmann::json::object()) {
    nlohmann::json e = {{"type", "scatter"}, {"count", 25}, {"area", {{-5, -5}, {5, 5}}}, {"source", source}, {"seed", 4}};
    e.merge_patch(extra);
    return e;
}

}  // namespace

TEST_CASE("scatter: deterministic, and cached and re-streamed sources give the same bytes", "[procedural]") {
    const nlohmann::json tree = {{"type", "tree"}, {"depth", 2}};
    requireDeterministic(scatterOf(tree));
    requireDeterministic(scatterOf(tree, {{"cache_triangles", 0}}));
    CHECK(hashWithThreads(scatterOf(tree, {{"cache_triangles", 0}}), 1) == hashWithThreads(scatterOf(tree), 2));
    CHECK(hashWithThreads(scatterOf(tree, {{"cache_triangles", 100}}), 2) == hashWithThreads(scatterOf(tree), 1));
    // A scatter of scatters works too.
    requireDeterministic(scatterOf(scatterOf(tree, {{"count", 3}}), {{"count", 4}}));
    CHECK(openEntry(scatterOf(scatterOf(tree, {{"count", 3}}), {{"count", 4}}))->sizeHint() ==
          12 * openEntry(tree)->sizeHint().value());
}

TEST_CASE("scatter: instances of an OBJ file, placed, turned and scaled as documented", "[procedural]") {
    registerFileSourceTypes();
    ScratchDir dir("scatter");
    // One triangle with its origin at a corner, 1 unit above the local origin.
    writeText(dir / "tri.obj", "v 0 1 0\nv 1 1 0\nv 0 1 1\nf 1 2 3\n");
    nlohmann::json e = scatterOf({{"type", "obj"}, {"path", "tri.obj"}},
                                 {{"count", 50}, {"scale", {2, 3}}, {"rotation_deg", {0, 360}}, {"base_height", 0.5}});
    TriangleSourcePtr source = openEntry(e, dir.path.string());
    REQUIRE(source->sizeHint() == 50u);
    std::vector<Triangle> tris = readAll(*source);
    REQUIRE(tris.size() == 50u);
    for (const Triangle& t : tris) {
        const double scale = glm::length(glm::dvec3(t.v[1]) - glm::dvec3(t.v[0]));
        CHECK(scale >= 2 - 1e-5);
        CHECK(scale <= 3 + 1e-5);
        // The local origin sits on the plane y = 0.5, so the triangle floats at 0.5 + scale.
        for (const glm::vec3& v : t.v) CHECK(v.y == Approx(0.5 + scale).epsilon(1e-5));
        // Rotation is about +y only: the right angle at v0 survives.
        CHECK(std::abs(glm::dot(glm::dvec3(t.v[1] - t.v[0]), glm::dvec3(t.v[2] - t.v[0]))) < 1e-4);
        // Positions inside the area (the origin of each instance is v0 minus the lift).
        CHECK(std::abs(t.v[0].x) <= 5 + 1e-5);
        CHECK(std::abs(t.v[0].z) <= 5 + 1e-5);
    }
    // The inline source's own transform is applied before the placement.
    nlohmann::json lifted = e;
    lifted["source"]["transform"] = {{"translate", {0, 1, 0}}};
    std::vector<Triangle> up = readAll(*openEntry(lifted, dir.path.string()));
    for (size_t i = 0; i < tris.size(); ++i) {
        const double scale = glm::length(glm::dvec3(up[i].v[1]) - glm::dvec3(up[i].v[0]));
        CHECK(up[i].v[0].y == Approx(0.5 + 2 * scale).epsilon(1e-5));
    }
    // Re-streaming the file per instance gives the same bytes as keeping it.
    nlohmann::json streamed = e;
    streamed["cache_triangles"] = 0;
    TriangleSourcePtr a = openEntry(streamed, dir.path.string());
    TriangleSourcePtr b = openEntry(e, dir.path.string());
    CHECK(streamHash(*a, 7) == streamHash(*b));
}

TEST_CASE("scatter: instances stand on an inline terrain", "[procedural]") {
    const nlohmann::json terrain = {{"area", {{-6, -6}, {6, 6}}}, {"resolution", 10}, {"amplitude", 1}, {"frequency", 0.2}};
    nlohmann::json e = scatterOf({{"type", "boxes"}, {"boxes", {{{-0.1, 0, -0.1}, {0.1, 0.2, 0.1}}}}},
                                 {{"terrain", terrain}, {"rotation_deg", 0}, {"count", 30}});
    std::vector<Triangle> tris = readAll(*openEntry(e));
    REQUIRE(tris.size() == 30u * 12);
    nlohmann::json tp = terrain;
    TerrainParams p = parseTerrainParams(JsonParams(tp, "scene.json", "terrain"));
    for (size_t k = 0; k < 30; ++k) {
        glm::dvec3 lo(1e9), hi(-1e9);
        for (size_t i = 0; i < 12; ++i)
            for (const glm::vec3& v : tris[k * 12 + i].v) lo = glm::min(lo, glm::dvec3(v)), hi = glm::max(hi, glm::dvec3(v));
        const glm::dvec3 centre = 0.5 * (lo + hi);
        CHECK(lo.y == Approx(terrainHeight(p, centre.x, centre.z)).margin(1e-5));
    }
}

TEST_CASE("scatter: bad parameters give an error naming the key", "[procedural]") {
    const nlohmann::json tree = {{"type", "tree"}, {"depth", 1}};
    requireInputError({{"type", "scatter"}, {"count", 3}}, "scene.json: geometry[0].source: missing required field");
    requireInputError(scatterOf(tree, {{"count", -1}}), "geometry[0].count: must be in 0..");
    requireInputError(scatterOf(tree, {{"area", {{0, 0}, {0, 1}}}}), "geometry[0].area: area is empty");
    requireInputError(scatterOf(tree, {{"scale", {0, 1}}}), "geometry[0].scale: must lie in (0");
    requireInputError(scatterOf({{"type", "teapot"}}), "geometry[0].source: unknown geometry type \"teapot\"");
    requireInputError(scatterOf({{"depth", 1}}), "geometry[0].source.type: missing required field");
    requireInputError(scatterOf({{"type", "tree"}, {"depth", 40}}), "geometry[0].source.depth: must be in 0..12");
    requireInputError(scatterOf({{"type", "tree"}, {"transform", {{"spin", 1}}}}), "geometry[0].source.transform.spin: unknown key");
    requireInputError(scatterOf(tree, {{"count", 4611686018427387904}}), "geometry[0].count: ");
    // Documented keys of top-level entries were called unknown inside a source.
    requireInputError(scatterOf({{"type", "tree"}, {"depth", 1}, {"leaf_texture", "leaf.png"}}),
                      "geometry[0].source.leaf_texture: is read on top-level tree, forest and flowers entries only");
    requireInputError(scatterOf({{"type", "tree"}, {"depth", 1}, {"cast_shadows", false}}),
                      "geometry[0].source.cast_shadows: is an object control of top-level entries: give it on the scatter entry");
}
