// Generated lightmap atlases: no two charts share a texel, the gutter keeps each chart's padding
// its own, the atlas is well used on the example and on real meshes, the result does not depend
// on the thread count, and broken input (degenerate triangles, non-manifold edges, surfaces that
// overlap in projection) is cut without crashing. Also the crease-angle shading normals.

#include "AtlasChecks.h"
#include "TestSupport.h"

#include "receivers/ChartParameterization.h"
#include "receivers/CreaseNormals.h"
#include "receivers/LightmapAtlas.h"
#include "stream/IndexedMesh.h"

#include <catch2/catch.hpp>
#include <glm/geometric.hpp>
#include <tbb/global_control.h>

#include <cmath>
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

TEST_CASE("atlas: real meshes without UVs pack over 60% of the atlas", "[atlas]") {
    const int padding = 2;
    for (const char* name : {"cow.obj", "teapot.obj", "spot.obj"}) {
        IndexedMesh mesh = load(sharedData(std::string("meshes/") + name));
        LightmapAtlas atlas = atlasOf({mesh}, 1024, padding);
        INFO(name);
        const double used = requireSound(atlas, padding);
        WARN(name << " at 1024, padding 2: " << atlas.charts << " charts, " << 100 * used << "% covered");
        CHECK(used >= 0.60);
    }
}
