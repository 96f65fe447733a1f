// The pipeline's hooks for library callers (the Python module): a captured bake hands back the
// same results the files hold and writes the same bytes later; the cancel flag stops a bake
// leaving nothing behind; the progress snapshot names the phase running now.

#include "CliRunner.h"

#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "procedural/Generators.h"
#include "stream/util/Npy.h"
#include "stream/util/Progress.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <cstring>
#include <fstream>
#include <iterator>

using namespace penumbra;
using namespace penumbra::test;

namespace {

const std::string kFloor = std::string(PENUMBRA_SOURCE_DIR) + "/examples/vertices-floor.glb";

std::string bytesOf(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

/// A row of points across the shadow of a blocker over the example floor; output @p output.
SceneDesc pointsScene(const ScratchDir& dir, const std::string& output) {
    registerFileSourceTypes();
    registerProceduralGenerators();
    std::vector<float> rows;
    for (int i = 0; i < 50; ++i) rows.insert(rows.end(), {-3.f + 0.12f * float(i), 0.01f, 0.f, 0.f, 1.f, 0.f});
    const uint64_t shape[2] = {50, 6};
    writeNpy(dir / "pts.npy", "<f4", shape, rows.data(), rows.size() * sizeof(float));
    nlohmann::json scene = {
        {"geometry", {{{"type", "glb"}, {"path", kFloor}},
                      {{"type", "grid"}, {"size", 1.2}, {"cells", 6}, {"bar", 0.8}, {"levels", 1}, {"height", 1.2}, {"floor_size", 0}}}},
        {"lights", {{{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}, {"samples", 64}}}},
        {"receivers", {{"type", "points"}, {"path", "pts.npy"}}},
        {"output", output}};
    return parseScene(scene, dir / "scene.json");
}

BakeSettings quietSettings() {
    BakeSettings settings;
    settings.quiet = true;
    settings.threads = 2;
    return settings;
}

}  // namespace

TEST_CASE("capture: a captured bake holds what the CLI writes, and writes the same bytes later", "[python][pipeline]") {
    ScratchDir dir("capture");
    AllowOutsidePaths examples;
    BakeSettings plain = quietSettings();
    plain.dumpDir = dir / "dump";
    runBake(pointsScene(dir, "plain.npy"), plain);

    BakeCapture capture;
    capture.wantMasks = true;
    BakeSettings settings = quietSettings();
    settings.capture = &capture;
    const SceneDesc scene = pointsScene(dir, "captured.npy");
    nlohmann::json stats = runBake(scene, settings);
    CHECK_FALSE(std::filesystem::exists(dir / "captured.npy"));  // writeOutputs false: nothing written
    REQUIRE(capture.kind);
    REQUIRE(capture.receivers.size() == 50);
    CHECK(stats["receivers"] == 50);

    NpyArray visibility = readNpy(dir / "plain.npy");
    REQUIRE(visibility.data.size() == 50 * sizeof(float));
    CHECK(std::memcmp(visibility.data.data(), capture.results.visibility.data(), visibility.data.size()) == 0);
    NpyArray masks = readNpy(dir / "dump/masks.npy");
    const std::vector<uint64_t> dense = capture.masks.toDumpLayout(capture.samples);
    REQUIRE(masks.data.size() == dense.size() * sizeof(uint64_t));
    CHECK(std::memcmp(masks.data.data(), dense.data(), masks.data.size()) == 0);
    float lo = 1, hi = 0;
    for (float v : capture.results.visibility) lo = std::min(lo, v), hi = std::max(hi, v);
    CHECK(lo < 1.0f);  // the blocker shadows part of the row, and light reaches beside it
    CHECK(hi == 1.0f);

    writeCapturedOutputs(scene, capture, dir / "later.npy");
    CHECK(bytesOf(dir / "later.npy") == bytesOf(dir / "plain.npy"));
}

TEST_CASE("capture: requestCancel stops a bake with Cancelled, leaving no output", "[python][pipeline]") {
    ScratchDir dir("cancel");
    AllowOutsidePaths examples;
    requestCancel();
    CHECK_THROWS_AS(runBake(pointsScene(dir, "cancelled.npy"), quietSettings()), Cancelled);
    clearCancel();
    CHECK_FALSE(std::filesystem::exists(dir / "cancelled.npy"));
    runBake(pointsScene(dir, "after.npy"), quietSettings());  // cleared: the next bake runs
    CHECK(std::filesystem::exists(dir / "after.npy"));
}

TEST_CASE("progress: currentProgress names the newest running phase, quiet or not", "[python][progress]") {
    CHECK_FALSE(currentProgress());
    {
        ProgressReporter outer("outer", 10, true);
        outer.update(3);
        std::optional<ProgressSnapshot> s = currentProgress();
        REQUIRE(s);
        CHECK(s->phase == "outer");
        CHECK(s->done == 3);
        CHECK(s->total == 10);
        {
            ProgressReporter inner("inner", 0, true);
            CHECK(currentProgress()->phase == "inner");
        }
        CHECK(currentProgress()->phase == "outer");
    }
    CHECK_FALSE(currentProgress());
}
