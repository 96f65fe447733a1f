// The camera sees through cut-outs (issue #15): a pixel whose nearest surface is a clear texel of
// an alpha triangle gets the surface behind it as its receiver. Checked against the analytic
// answer (where the pixel ray meets the cut-out's plane, the outline or the checker cell
// decides), for a built-in leaf outline rasterized directly and for a glTF MASK checkerboard
// baked through the whole pipeline's camera kind.

#include "GltfAlphaFiles.h"
#include "TestScenes.h"

#include "bake/BakeCapture.h"
#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "procedural/Generators.h"
#include "receivers/CameraReceivers.h"
#include "stream/AlphaTable.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <functional>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// A camera straight above the origin, looking down at a cut-out at y = 1 over a floor at y = 0.
CameraDesc topCamera() {
    CameraDesc c;
    c.eye = {0.1, 5, 0.05}, c.target = {0.1, 0, 0.05}, c.up = {0, 0, -1};
    c.fovDeg = 40, c.width = 96, c.height = 96;
    return c;
}

/// Where the pixel ray of receiver @p i meets y = 1, as (x, z).
glm::dvec2 hitOnCutOutPlane(const CameraDesc& c, const ReceiverSet& set, size_t i) {
    const uint32_t p = set.pixel[i];
    const glm::dvec3 d = c.pixelDirection(int(p % uint32_t(c.width)), int(p / uint32_t(c.width)));
    const double s = (1.0 - c.eye.y) / d.y;
    return {c.eye.x + s * d.x, c.eye.z + s * d.z};
}

/// Every pixel sees the floor (y = 0) or the cut-out (y = 1) as @p opaqueAt says of the hit on
/// y = 1 (nullopt: too close to an edge or outline to call); @return the pixels on each.
std::pair<size_t, size_t> requireSeenThrough(const CameraDesc& c, const ReceiverSet& set,
                                             const std::function<std::optional<bool>(glm::dvec2)>& opaqueAt) {
    REQUIRE(set.size() == size_t(c.width) * c.height);  // the floor covers the whole view
    size_t onCutOut = 0, onFloor = 0, wrong = 0;
    for (size_t i = 0; i < set.size(); ++i) {
        const std::optional<bool> opaque = opaqueAt(hitOnCutOutPlane(c, set, i));
        if (!opaque) continue;
        const double expectedY = *opaque ? 1.0 : 0.0;
        const bool ok = std::abs(set.position[i].y - expectedY) < 1e-4 && set.normal[i].y > 0.999f;
        wrong += !ok;
        (*opaque ? onCutOut : onFloor) += 1;
    }
    CHECK(wrong == 0);
    return {onCutOut, onFloor};
}

/// The floor [-4, 4]^2 at y = 0, as two opaque triangles facing up.
void addFloor(std::vector<Triangle>& out) {
    const glm::vec3 a(-4, 0, -4), b(4, 0, -4), c(4, 0, 4), d(-4, 0, 4);
    out.push_back({{a, c, b}, 0});
    out.push_back({{a, d, c}, 0});
}

}  // namespace

TEST_CASE("camera cut-outs: the camera sees the floor through a leaf outline's clear part", "[alpha][camera]") {
    // The canonical quad layout of the built-in leaf: corners (0,0) (1,0) (1,1) (0,1) map to
    // x = 2u - 1, z = 2v - 1 at y = 1.
    std::vector<Triangle> tris;
    const glm::vec3 p[4] = {{-1, 1, -1}, {1, 1, -1}, {1, 1, 1}, {-1, 1, 1}};
    tris.push_back({{p[0], p[1], p[2]}, withAlphaId(0, kAlphaLeafLower)});
    tris.push_back({{p[0], p[2], p[3]}, withAlphaId(0, kAlphaLeafUpper)});
    addFloor(tris);
    const CameraDesc c = topCamera();
    auto leaf = [](glm::dvec2 xz) -> std::optional<bool> {
        const double u = (xz.x + 1) / 2, v = (xz.y + 1) / 2;
        if (u < 0 || u > 1 || v < 0 || v > 1) return false;  // outside the quad: the floor
        const double f = 4 * u * (1 - u) - std::abs(2 * v - 1);
        if (std::abs(f) < 1e-3 || std::abs(u) < 1e-3 || std::abs(u - 1) < 1e-3 || std::abs(v) < 1e-3 ||
            std::abs(v - 1) < 1e-3)
            return std::nullopt;
        return f > 0;
    };
    VectorSource source(tris);
    const ReceiverSet seen = rasterizeCamera(source, c, {}, AlphaTable::builtin());
    const auto [onLeaf, onFloor] = requireSeenThrough(c, seen, leaf);
    CHECK(onLeaf > 500);
    CHECK(onFloor > 500);

    // Without the table the camera sees the whole quad, as before.
    VectorSource again(tris);
    const ReceiverSet solid = rasterizeCamera(again, c);
    const auto [onQuad, outside] = requireSeenThrough(c, solid, [&](glm::dvec2 xz) -> std::optional<bool> {
        const std::optional<bool> l = leaf(xz);
        if (!l) return l;
        return std::abs(xz.x) < 1 && std::abs(xz.y) < 1;
    });
    CHECK(onQuad > onLeaf);
    CHECK(outside < onFloor);

    // Deterministic whatever the order of the chunks: the same receivers from the reversed stream.
    std::vector<Triangle> reversed(tris.rbegin(), tris.rend());
    VectorSource back(reversed);
    const ReceiverSet seenBack = rasterizeCamera(back, c, {}, AlphaTable::builtin());
    CHECK(seenBack.position == seen.position);
}

TEST_CASE("camera cut-outs: a camera bake of a glTF MASK checkerboard sees the floor through its clear texels",
          "[alpha][camera][gltf]") {
    const int n = 8;
    ScratchDir dir("camera-cutouts");
    writeCheckerQuad(dir / "quad.glb", n, "view");
    registerFileSourceTypes();
    registerProceduralGenerators();
    const CameraDesc c = topCamera();
    const json scene = {
        {"geometry", json::array({json{{"type", "file"}, {"path", "quad.glb"}},
                                  json{{"type", "grid"}, {"levels", 0}, {"floor_size", 8}}})},
        {"lights", json::array({json{{"type", "rect"}, {"center", {0, 3, 0}}, {"u", {0.3, 0, 0}}, {"v", {0, 0, 0.3}},
                                     {"samples", 16}}})},
        {"receivers", {{"type", "camera"}, {"eye", {c.eye.x, c.eye.y, c.eye.z}}, {"target", {c.target.x, c.target.y, c.target.z}},
                       {"up", {c.up.x, c.up.y, c.up.z}}, {"fov_deg", c.fovDeg}, {"width", c.width}, {"height", c.height}}},
        {"output", "out.exr"}};
    const SceneDesc desc = parseScene(scene, (dir.path / "scene.json").string());
    BakeCapture capture;
    BakeSettings settings;
    settings.quiet = true, settings.threads = 2, settings.method = "hpc", settings.capture = &capture;
    runBake(desc, settings);
    // The quad's uv = ((x + 1) / 2, (z + 1) / 2); texel (i, j) is opaque when i + j is even.
    const auto [onQuad, onFloor] = requireSeenThrough(c, capture.receivers, [&](glm::dvec2 xz) -> std::optional<bool> {
        const double cu = (xz.x + 1) / 2 * n, cv = (xz.y + 1) / 2 * n;
        if (std::abs(cu - std::round(cu)) < 1e-3 || std::abs(cv - std::round(cv)) < 1e-3) return std::nullopt;
        if (cu < 0 || cu > n || cv < 0 || cv > n) return false;
        return (int(std::floor(cu)) + int(std::floor(cv))) % 2 == 0;
    });
    CHECK(onQuad > 500);
    CHECK(onFloor > 500);
}
