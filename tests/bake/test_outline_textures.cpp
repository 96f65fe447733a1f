// Generators' leaf and petal textures (issue #15): "leaf_texture" on tree/forest and
// "petal_texture" on flowers replace the built-in outline with a PNG's alpha on the same
// canonical quad layout. A texture that is the analytic outline rasterized gives nearly the
// outline's visibility; hpc equals the reference bit for bit on textured leaves; bad input is a
// one-line error naming the scene file and the key.

#include "TestScenes.h"

#include "bake/BakeCapture.h"
#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "procedural/Generators.h"
#include "stream/GlbBuilder.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/Npy.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <functional>

using namespace penumbra;
using namespace penumbra::test;
using json = nlohmann::json;

namespace {

/// An n x n RGBA PNG whose texel (i, j) is opaque where @p inside holds at its centre
/// (u, v) = ((i + 0.5) / n, (j + 0.5) / n), row j at v.
void writeOutlinePng(const std::string& path, int n, const std::function<bool(double, double)>& inside) {
    std::vector<uint8_t> rgba(size_t(n) * n * 4, 90);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) rgba[(size_t(j) * n + i) * 4 + 3] = inside((i + 0.5) / n, (j + 0.5) / n) ? 255 : 0;
    writeFileAtomically(path, encodePngRgba(n, n, rgba));
}

bool leafOutline(double u, double v) { return 4 * u * (1 - u) - std::abs(2 * v - 1) > 0; }
bool petalOutline(double u, double v) { return (2 * u - 1) * (2 * u - 1) + (2 * v - 1) * (2 * v - 1) < 1; }

/// A 40 x 40 grid of points on the floor y = 0 under the foliage, facing up.
json floorPoints(const ScratchDir& dir) {
    writeFloorPoints(dir.path / "pts.npy", 40, -1.95f, 0.1f);
    return {{"type", "points"}, {"path", "pts.npy"}};
}

json treeEntry() {
    return {{"type", "tree"}, {"depth", 3}, {"leaves_per_branch", 10}, {"leaf_size", 0.35}, {"trunk_length", 1.0}};
}

json flowersEntry() {
    return {{"type", "flowers"}, {"count", 40}, {"area", {{-1.5, -1.5}, {1.5, 1.5}}}, {"petal_length", {0.3, 0.45}}};
}

SceneDesc foliageScene(const ScratchDir& dir, const json& entry) {
    registerFileSourceTypes();
    registerProceduralGenerators();
    const json light = {{"type", "rect"}, {"center", {0.3, 4, 0.2}}, {"u", {0.4, 0, 0}}, {"v", {0, 0, 0.4}}, {"samples", 64}};
    const json scene = {{"geometry", json::array({entry})}, {"lights", json::array({light})}, {"receivers", floorPoints(dir)},
                        {"output", "out.npy"}};
    return parseScene(scene, (dir.path / "scene.json").string());
}

BakeCapture bake(const SceneDesc& scene, const std::string& method) {
    BakeCapture capture;
    capture.wantMasks = true;
    BakeSettings settings;
    settings.quiet = true, settings.threads = 2, settings.method = method, settings.capture = &capture;
    runBake(scene, settings);
    return capture;
}

/// The InputError message of parsing and baking @p entry, or "" when none is thrown.
std::string errorOf(const ScratchDir& dir, const json& entry) {
    try {
        bake(foliageScene(dir, entry), "hpc");
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST_CASE("outline textures: a texture equal to the analytic outline gives nearly its visibility, leaves and petals",
          "[alpha][procedural]") {
    struct Case {
        const char* name;
        json entry;
        const char* key;
        bool (*outline)(double, double);
    };
    for (const Case& c : {Case{"tree", treeEntry(), "leaf_texture", leafOutline}, Case{"flowers", flowersEntry(), "petal_texture", petalOutline}}) {
        INFO(c.name);
        ScratchDir dir("outline-texture");
        writeOutlinePng((dir.path / "outline.png").string(), 256, c.outline);
        const BakeCapture analytic = bake(foliageScene(dir, c.entry), "hpc");
        json textured = c.entry;
        textured[c.key] = "outline.png";
        const SceneDesc scene = foliageScene(dir, textured);
        const BakeCapture fromTexture = bake(scene, "hpc");
        // One map and the lower and upper entries of the canonical quad after the built-in ids.
        CHECK(scene.options.alphaTable->entries() == kBuiltinAlphaCount + 2);
        REQUIRE(fromTexture.results.visibility.size() == analytic.results.visibility.size());
        double sumDiff = 0, maxDiff = 0, sumShadow = 0;
        for (size_t r = 0; r < analytic.results.visibility.size(); ++r) {
            const double d = std::abs(double(fromTexture.results.visibility[r]) - double(analytic.results.visibility[r]));
            sumDiff += d, maxDiff = std::max(maxDiff, d), sumShadow += 1.0 - analytic.results.visibility[r];
        }
        const double n = double(analytic.results.visibility.size());
        CHECK(sumShadow / n > 0.02);           // the foliage does shade the floor
        CHECK(sumDiff / n < 0.002);            // texels of 1/256 of a leaf: a sliver of difference
        CHECK(maxDiff <= 6.0 / 64 + 1e-6);     // at most a few of a receiver's 64 samples
        CHECK(sumDiff > 0);                    // and the texture, not the outline, was tested
    }
}

TEST_CASE("outline textures: hpc equals the reference bit for bit on textured generated leaves and petals", "[alpha][procedural]") {
    ScratchDir dir("outline-texture-exact");
    // A texture unlike the outline (stripes with holes) so that the test is the texture's.
    writeOutlinePng((dir.path / "stripes.png").string(), 16, [](double u, double v) { return int(u * 16) % 3 != 0 && int(v * 16) % 4 != 1; });
    for (json entry : {treeEntry(), flowersEntry()}) {
        entry[entry["type"] == "tree" ? "leaf_texture" : "petal_texture"] = "stripes.png";
        entry["alpha_cutoff"] = 0.6;
        const SceneDesc scene = foliageScene(dir, entry);
        const BakeCapture hpc = bake(scene, "hpc"), reference = bake(scene, "reference");
        CHECK(hpc.masks.words == reference.masks.words);
        CHECK(hpc.results.visibility == reference.results.visibility);
    }
}

TEST_CASE("outline textures: bad input is a one-line error naming the scene file and the key", "[alpha][procedural]") {
    ScratchDir dir("outline-texture-errors");
    const std::string file = (dir.path / "scene.json").string();
    writeFileAtomically((dir.path / "notpng.png").string(), std::vector<uint8_t>{'h', 'e', 'l', 'l', 'o'});
    auto expectError = [&](json entry, const std::string& key, const std::string& what) {
        const std::string message = errorOf(dir, entry);
        INFO(message);
        CHECK(message.find(file + ": geometry[0]." + key) != std::string::npos);
        CHECK(message.find(what) != std::string::npos);
        CHECK(message.find('\n') == std::string::npos);
    };
    json tree = treeEntry();
    tree["leaf_texture"] = "missing.png";
    expectError(tree, "leaf_texture", "missing.png");
    tree["leaf_texture"] = "notpng.png";
    expectError(tree, "leaf_texture", "not a PNG or JPEG");
    tree["leaf_texture"] = "notpng.png", tree["alpha_cutoff"] = 1.5;
    expectError(tree, "alpha_cutoff", "1.5");
    json flowers = flowersEntry();
    flowers["leaf_texture"] = "notpng.png";
    expectError(flowers, "leaf_texture", "not an option");
    json grid = {{"type", "grid"}, {"levels", 0}, {"floor_size", 4}, {"alpha_cutoff", 0.5}};
    expectError(grid, "alpha_cutoff", "not an option");
    // No output and no temp file is left by a failed bake.
    CHECK(!std::filesystem::exists(dir.path / "out.npy"));
}

TEST_CASE("outline textures: the memory plan counts them, and one that alone exceeds the budget is refused",
          "[alpha][procedural]") {
    ScratchDir dir("outline-texture-budget");
    // 4096 x 4096 RGBA: 128 MiB to decode (twice the pixels), 2 MiB of bits.
    writeOutlinePng((dir.path / "big.png").string(), 4096, leafOutline);
    json tree = treeEntry();
    tree["leaf_texture"] = "big.png";
    const SceneDesc scene = foliageScene(dir, tree);
    BakeCapture capture;
    BakeSettings settings;
    settings.quiet = true, settings.threads = 1, settings.capture = &capture, settings.memoryBudget = 64ull << 20;
    try {
        runBake(scene, settings);
        FAIL("a 4096^2 texture baked within 64 MiB");
    } catch (const InputError& e) {
        const std::string message = e.what();
        INFO(message);
        CHECK(message.find("geometry[0].leaf_texture") != std::string::npos);
        CHECK(message.find("4096 x 4096") != std::string::npos);
    }
    CHECK(!std::filesystem::exists(dir.path / "out.npy"));
}
