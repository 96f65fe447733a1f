// Closed casters never lose a shadow: a light that reaches inside closed solids (boxes, a closed
// OBJ, grid bars) has those solids cast as open surfaces, says so, and matches the reference.

#include "CliRunner.h"
#include "TestSupport.h"

#include "bake/cast/ClosedSolids.h"
#include "stream/Npy.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <fstream>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// Receivers on the floor in a ring around the origin, facing up.
void writeFloorPoints(const ScratchDir& dir) {
    std::vector<float> pts;
    for (int i = 0; i < 24; ++i)
        for (int j = 0; j < 24; ++j)
            pts.insert(pts.end(), {-3.0f + 6.0f * i / 23, 0.0f, -3.0f + 6.0f * j / 23, 0, 1, 0});
    uint64_t shape[2] = {pts.size() / 6, 6};
    writeNpy(dir / "floor.npy", "<f4", shape, pts.data(), pts.size() * sizeof(float));
}

struct Bakes {
    nlohmann::json stats;
    std::string err;
};

/// Bakes @p scene with hpc (closed casters on) and the reference, and requires identical masks.
Bakes requireReferenceMasks(const ScratchDir& dir, const nlohmann::json& scene, const std::string& name) {
    std::ofstream(dir / (name + ".json")) << scene.dump();
    RunResult hpc = runPenumbra("bake " + (dir / (name + ".json")) + " --closed-casters on --allow-outside-uris --dump " + (dir / (name + "-hpc")) +
                                " --stats " + (dir / (name + ".stats.json")) + " -o " + (dir / (name + "-hpc.npy")));
    INFO(hpc.err);
    REQUIRE(hpc.exitCode == 0);
    RunResult ref = runPenumbra("bake " + (dir / (name + ".json")) + " -q --method reference --allow-outside-uris --dump " + (dir / (name + "-ref")) +
                                " -o " + (dir / (name + "-ref.npy")));
    REQUIRE(ref.exitCode == 0);
    RunResult cmp = runPenumbra("compare " + (dir / (name + "-hpc")) + " " + (dir / (name + "-ref")));
    INFO(cmp.out);
    CHECK(cmp.exitCode == 0);
    CHECK_THAT(cmp.out, Catch::Contains("only_a 0\n") && Catch::Contains("only_b 0\n"));
    CHECK_THAT(cmp.out, !Catch::Contains("blocked_a 0\n"));  // something is in shadow
    return {nlohmann::json::parse(slurp(dir / (name + ".stats.json"))), hpc.err};
}

nlohmann::json floorQuad() {
    return {{"type", "boxes"}, {"boxes", {{{-4, -0.2, -4}, {4, -0.1, 4}}}}, {"closed", false}};
}

nlohmann::json scene(const nlohmann::json& geometry, const nlohmann::json& light) {
    return {{"geometry", geometry}, {"lights", {light}}, {"receivers", {{"type", "points"}, {"path", "floor.npy"}}},
            {"output", "out.npy"}};
}

}  // namespace

TEST_CASE("a rect light inside two closed boxes keeps every shadow", "[closed][exact]") {
    ScratchDir dir("closed");
    writeFloorPoints(dir);
    const nlohmann::json boxes = {{"type", "boxes"},
                                  {"boxes", {{{-1, 0.2, -1}, {0, 1.2, 0}}, {{0.2, 0.2, 0.2}, {1.2, 1.2, 1.2}}, {{2, 0, 2}, {2.5, 0.5, 2.5}}}}};
    // At y = 0.7 the light crosses both of the first boxes and the gap between them.
    const nlohmann::json light = {{"type", "rect"}, {"center", {0.1, 0.7, 0.1}}, {"u", {2.4, 0, 0}}, {"v", {0, 0, 2.4}},
                                  {"samples", 64}};
    Bakes b = requireReferenceMasks(dir, scene({floorQuad(), boxes}, light), "boxes");
    CHECK(b.stats["counters"]["closed_solids_opened"] == 2);  // not the third box
    CHECK(b.stats["counters"]["closed_triangles_opened"] == 24);
    CHECK(b.stats["counters"]["closed_back_faces_skipped"].get<uint64_t>() > 0);  // the third box still culls
    CHECK_THAT(b.err, Catch::Contains("lights[0] reaches inside 2 closed solid(s)"));
}

TEST_CASE("a light inside a closed OBJ (spot.obj) keeps its shadow", "[closed][exact]") {
    ScratchDir dir("closed-obj");
    writeFloorPoints(dir);
    const nlohmann::json spot = {{"type", "obj"}, {"path", sharedData("meshes/spot.obj")}, {"closed", true},
                                 {"transform", {{"translate", {0, 0.8, 0}}}}};
    const nlohmann::json light = {{"type", "sphere"}, {"center", {0, 0.9, 0.1}}, {"radius", 0.05}, {"samples", 64}};
    Bakes b = requireReferenceMasks(dir, scene({floorQuad(), spot}, light), "spot");
    CHECK(b.stats["counters"]["closed_solids_opened"] == 1);
    CHECK(b.stats["counters"]["closed_triangles_opened"] == 5856);
}

TEST_CASE("a light straddling a grid bar opens that bar only", "[closed][exact]") {
    ScratchDir dir("closed-grid");
    writeFloorPoints(dir);
    // size 2, 4 cells: bar 0 runs along x at z in [-1.1, -0.9], y in [0.5, 0.7].
    const nlohmann::json grid = {{"type", "grid"}, {"size", 2}, {"cells", 4}, {"bar", 0.4}, {"thickness", 0.2},
                                 {"levels", 1}, {"height", 0.6}, {"floor_size", 0}};
    const nlohmann::json light = {{"type", "rect"}, {"center", {0, 0.6, -1.05}}, {"u", {0.3, 0, 0}}, {"v", {0, 0, 0.26}},
                                  {"samples", 64}};
    Bakes b = requireReferenceMasks(dir, scene({floorQuad(), grid}, light), "grid");
    CHECK(b.stats["counters"]["closed_solids_opened"] == 1);
    CHECK(b.stats["counters"]["closed_triangles_opened"] == 12);
}

TEST_CASE("closed solids are segmented at solid starts and runs of closed triangles", "[closed]") {
    auto tri = [](float x, uint32_t flags) { return Triangle{{glm::vec3(x, 0, 0), glm::vec3(x + 1, 0, 0), glm::vec3(x, 1, 0)}, flags}; };
    const uint32_t c = kTriangleClosed, s = kTriangleClosed | kTriangleSolidStart;
    std::vector<Triangle> stream = {tri(0, s), tri(0, c), tri(5, s), tri(5, c), tri(9, 0), tri(20, c), tri(20, c)};
    SolidSegmenter seg;
    std::vector<uint64_t> ids;
    for (const Triangle& t : stream) ids.push_back(seg.next(t));
    CHECK(ids == std::vector<uint64_t>{0, 0, 1, 1, SolidSegmenter::kNone, 2, 2});
    // Only the solid whose box meets the light opens, and only its triangles lose the mark.
    LightSamples samples;
    ConvexBound b;
    b.vertices = {{5.5, 0.5, -0.1}, {5.6, 0.5, 0.1}};
    samples.lightBounds = {b};
    ClosedSolidScan scan(samples);
    scan.scan(stream);
    OpenedSolids opened = scan.finish();
    CHECK(opened.ordinals == std::vector<uint64_t>{1});
    CHECK(opened.triangles == 2);
    OpenSolidsSource open(std::make_unique<VectorSource>(stream), opened.ordinals);
    std::vector<Triangle> out = readAll(open);
    for (size_t i = 0; i < out.size(); ++i) CHECK(bool(out[i].flags & kTriangleClosed) == (i != 2 && i != 3 && i != 4));
    open.rewind();
    CHECK(readAll(open).size() == stream.size());
}
