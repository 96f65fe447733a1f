// `penumbra generate` end to end: the same bytes for every --threads, a count that `penumbra
// info` confirms, clean errors; the example scenes have the documented sizes; and
// `penumbra bench generators` runs.

#include "CliRunner.h"
#include "ProceduralTestUtil.h"

#include "bake/Scene.h"

using namespace penumbra;
using namespace penumbra::test;

namespace {

const char* kScene = R"({
  "geometry": [
    {"type": "terrain", "area": [[-2, -2], [2, 2]], "resolution": 10, "amplitude": 0.2, "seed": 2},
    {"type": "grass", "count": 3000, "terrain": {"area": [[-2, -2], [2, 2]], "resolution": 10, "amplitude": 0.2, "seed": 2},
     "clump": {"frequency": 0.7}},
    {"type": "tree", "depth": 3, "transform": {"translate": [0.5, 0, 0.5], "scale": 0.5}},
    {"type": "flowers", "count": 200, "area": [[-1, -1], [1, 1]], "base_height": 0.3},
    {"type": "scatter", "count": 5, "source": {"type": "tree", "depth": 1}, "cache_triangles": 0}
  ],
  "lights": [{"type": "rect", "center": [0, 4, 0], "u": [1, 0, 0], "v": [0, 0, 1]}],
  "receivers": {"type": "camera", "eye": [0, 3, 4], "target": [0, 0, 0], "width": 32, "height": 24}})";

void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

uint64_t expectedCount() {
    registerProceduralGenerators();
    SceneDesc scene = parseScene(nlohmann::json::parse(kScene), "scene.json");
    return openSceneGeometry(scene)->sizeHint().value();
}

}  // namespace

TEST_CASE("generate writes the same bytes for every --threads, and info reports the count", "[procedural][cli]") {
    ScratchDir dir("generate");
    write(dir / "scene.json", kScene);
    const uint64_t count = expectedCount();
    for (const char* ext : {".ptri", ".obj", ".glb"}) {
        INFO(ext);
        RunResult one = runPenumbra("generate " + (dir / "scene.json") + " -o " + (dir / (std::string("one") + ext)) + " --threads 1");
        RunResult two = runPenumbra("generate " + (dir / "scene.json") + " -o " + (dir / (std::string("two") + ext)) + " --threads 2 -q");
        INFO(one.err << two.err);
        REQUIRE(one.exitCode == 0);
        REQUIRE(two.exitCode == 0);
        CHECK_THAT(one.err, Catch::Contains(std::to_string(count) + " triangles"));
        // Only .ptri holds the petals' and leaves' outlines; the other formats say so (a warning,
        // which -q does not silence), naming how many: they were dropped without a word.
        if (std::string(ext) == ".ptri") CHECK(two.err.empty());
        else CHECK_THAT(two.err, Catch::StartsWith("penumbra: warning: " + (dir / (std::string("two") + ext)) + ": ") &&
                                     Catch::Contains("cut-out triangles (petal and leaf outlines) written as plain ones") &&
                                     Catch::Contains("write .ptri to keep them"));
        const std::string a = slurp(dir / (std::string("one") + ext)), b = slurp(dir / (std::string("two") + ext));
        CHECK(a.size() > 1000);
        CHECK(a == b);
        RunResult info = runPenumbra("info " + (dir / (std::string("two") + ext)));
        REQUIRE(info.exitCode == 0);
        CHECK_THAT(info.out, Catch::StartsWith("triangles " + std::to_string(count) + "\n"));
    }
    // The default thread count writes the same bytes too.
    REQUIRE(runPenumbra("generate " + (dir / "scene.json") + " -q -o " + (dir / "all.ptri")).exitCode == 0);
    CHECK(slurp(dir / "all.ptri") == slurp(dir / "one.ptri"));
}

TEST_CASE("generate reports bad scenes and options in one clean line", "[procedural][cli]") {
    ScratchDir dir("generate-bad");
    nlohmann::json s = nlohmann::json::parse(kScene);
    s["geometry"][1]["count"] = -4;
    write(dir / "neg.json", s.dump());
    RunResult r = runPenumbra("generate " + (dir / "neg.json") + " -o " + (dir / "out.ptri"));
    CHECK(r.exitCode == 1);
    CHECK(lineCount(r.err) == 1);
    CHECK_THAT(r.err, Catch::StartsWith("penumbra: error: ") && Catch::Contains("neg.json: geometry[1].count: must be in 0.."));

    s = nlohmann::json::parse(kScene);
    s["geometry"][0]["type"] = "mountain";
    write(dir / "unknown.json", s.dump());
    r = runPenumbra("generate " + (dir / "unknown.json") + " -o " + (dir / "out.ptri"));
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.err, Catch::Contains("unknown.json: geometry[0]: unknown geometry type \"mountain\""));

    write(dir / "ok.json", kScene);
    r = runPenumbra("generate " + (dir / "ok.json") + " -o " + (dir / "out.xyz"));
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.err, Catch::Contains("out.xyz"));
    r = runPenumbra("generate " + (dir / "ok.json") + " -o " + (dir / "out.ptri") + " --threads -2");
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.err, Catch::Contains("--threads"));
    CHECK_FALSE(std::filesystem::exists(dir / "out.ptri"));
}

TEST_CASE("generate refuses vertices that overflow float in every format, naming the entry", "[procedural][cli]") {
    // Seven nested scatters of scale 1e6 (every key in range) overflow float: bake and .ptri
    // refused them, .obj and .glb were written with "inf" and exit 0.
    ScratchDir dir("generate-overflow");
    nlohmann::json inner = {{"type", "boxes"}, {"boxes", {{{0, 0, 0}, {1, 1, 1}}}}};
    for (int i = 0; i < 7; ++i) inner = {{"type", "scatter"}, {"count", 1}, {"scale", 1e6}, {"source", inner}};
    nlohmann::json s = nlohmann::json::parse(kScene);
    s["geometry"] = nlohmann::json::array({{{"type", "grid"}, {"cells", 2}}, inner});
    write(dir / "scene.json", s.dump());
    for (const char* ext : {".obj", ".glb", ".gltf", ".ptri"}) {
        INFO(ext);
        RunResult r = runPenumbra("generate " + (dir / "scene.json") + " -q -o " + (dir / (std::string("out") + ext)));
        CHECK(r.exitCode == 1);
        CHECK(lineCount(r.err) == 1);
        CHECK_THAT(r.err, Catch::Contains("scene.json: geometry[1] (scatter): triangle 0 has a non-finite"));
        CHECK_FALSE(std::filesystem::exists(dir / (std::string("out") + ext)));
    }
    RunResult bake = runPenumbra("bake " + (dir / "scene.json") + " -q -o " + (dir / "out.exr"));
    CHECK(bake.exitCode == 1);
    CHECK_THAT(bake.err, Catch::Contains("geometry[1] (scatter)"));
    // Keys that multiply or place without a bound of their own.
    for (auto [key, value] : {std::pair{"center", nlohmann::json{1e30, 0, 0}}, {"rotate_step_deg", nlohmann::json(1e308)}}) {
        s["geometry"] = nlohmann::json::array({{{"type", "grid"}, {key, value}}});
        write(dir / "grid.json", s.dump());
        RunResult r = runPenumbra("generate " + (dir / "grid.json") + " -q -o " + (dir / "grid.obj"));
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.err, Catch::Contains(std::string("grid.json: geometry[0].") + key + ": must be within"));
    }
    s["geometry"] = nlohmann::json::array({{{"type", "colonnade"}, {"center", {0, -2e9, 0}}}});
    write(dir / "colonnade.json", s.dump());
    CHECK_THAT(runPenumbra("generate " + (dir / "colonnade.json") + " -q -o " + (dir / "c.obj")).err,
               Catch::Contains("colonnade.json: geometry[0].center: must be within +-1e9"));
}

TEST_CASE("generate warns about what a geometry file cannot hold", "[procedural][cli]") {
    ScratchDir dir("generate-drops");
    REQUIRE(runPenumbra("make-example gltf-tree -o " + (dir / "tree.glb")).exitCode == 0);
    write(dir / "pane.obj", "v 0 1 0\nv 1 1 0\nv 0 1 1\nf 1 2 3\n");
    nlohmann::json s = nlohmann::json::parse(kScene);
    s["geometry"] = nlohmann::json::array({{{"type", "gltf"}, {"path", "tree.glb"}},
                                           {{"type", "obj"}, {"path", "pane.obj"}, {"translucent", {{"color", {1, 0, 0}}, {"opacity", 0.5}}}},
                                           {{"type", "obj"}, {"path", "pane.obj"}, {"max_distance", 2}}});
    write(dir / "scene.json", s.dump());
    RunResult r = runPenumbra("generate " + (dir / "scene.json") + " -o " + (dir / "out.ptri"));
    INFO(r.err);
    CHECK(r.exitCode == 0);
    CHECK_THAT(r.err, Catch::Contains("tree.glb: 280 triangle(s) with cut-out or blended materials") &&
                          Catch::Contains("generate carries geometry"));
    CHECK_THAT(r.err, Catch::Contains("scene.json: geometry[1]: \"translucent\" not written"));
    CHECK_THAT(r.err, Catch::Contains("scene.json: geometry[2]: \"max_distance\" not written"));
    // An output no format matches is refused first: one line, none of the warnings above.
    RunResult stl = runPenumbra("generate " + (dir / "scene.json") + " -o " + (dir / "out.stl"));
    CHECK(stl.exitCode == 1);
    CHECK(stl.err == "penumbra: error: " + (dir / "out.stl") + ": unknown output extension '.stl' (expected .obj, .gltf, .glb or .ptri)\n");
}

TEST_CASE("generate under an address-space limit names one that works before building anything", "[procedural][cli][memory]") {
    // A forest's variants are built on the first read: generating failed with a bare "out of
    // memory" at every limit, even one far above what it then needed.
    ScratchDir dir("generate-limit");
    nlohmann::json s = nlohmann::json::parse(kScene);
    s["geometry"] = {{{"type", "forest"}, {"count", 4}, {"area", {{0, 0}, {4, 4}}}, {"variants", 24}, {"depth", 6},
                      {"branches", 3}, {"sides", 16}, {"leaves_per_branch", 20}}};
    write(dir / "forest.json", s.dump());
    RunResult r = runPenumbra("generate " + (dir / "forest.json") + " -q -o " + (dir / "out.ptri"), "prlimit --as=" + std::to_string(120 << 20));
    INFO(r.err);
    REQUIRE(r.exitCode == 1);
    CHECK(lineCount(r.err) == 1);
    CHECK_THAT(r.err, Catch::Contains("forest keeps 24 variants"));
    CHECK_FALSE(std::filesystem::exists(dir / "out.ptri"));
    const size_t at = r.err.find("at least ");
    REQUIRE(at != std::string::npos);
    const uint64_t named = std::stoull(r.err.substr(at + 9));
    r = runPenumbra("generate " + (dir / "forest.json") + " -q -o " + (dir / "out.ptri"), "prlimit --as=" + std::to_string(named << 20));
    CHECK(r.exitCode == 0);
    CHECK(std::filesystem::exists(dir / "out.ptri"));
}

TEST_CASE("the example scenes have the documented sizes", "[procedural]") {
    registerProceduralGenerators();
    registerFileSourceTypes();
    auto count = [](const std::string& name) {
        SceneDesc scene = loadScene(std::string(PENUMBRA_SOURCE_DIR) + "/examples/" + name);
        return double(openSceneGeometry(scene)->sizeHint().value());
    };
    CHECK(count("grids.json") == Approx(73e3).epsilon(0.02));
    CHECK(count("flowers.json") == Approx(900e3).epsilon(0.02));
    CHECK(count("sponza-like.json") == Approx(1.3e6).epsilon(0.02));
    CHECK(count("meadow-1b.json") == Approx(1e9).epsilon(0.02));  // nothing is generated to count it
}

TEST_CASE("bench generators measures every generator", "[procedural][cli]") {
    ScratchDir dir("bench");
    RunResult r = runPenumbra("bench generators --triangles 20000 --threads 1 --json " + (dir / "gen.json"));
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    for (const char* name : {"| grass |", "| terrain |", "| tree |", "| forest |", "| flowers |", "| scatter", "| grid |"})
        CHECK_THAT(r.out, Catch::Contains(name));
    nlohmann::json j = nlohmann::json::parse(slurp(dir / "gen.json"));
    for (const auto& g : j["generators"]) CHECK(g["results"][0]["triangles_per_second"].get<double>() > 0);
    // An unwritable --json is refused before the measuring, not after it.
    write(dir / "afile", "x");
    RunResult late = runPenumbra("bench generators --triangles 20000 --threads 1 --json " + (dir / "afile/gen.json"));
    CHECK(late.exitCode == 1);
    CHECK(late.out.empty());
    CHECK_THAT(late.err, Catch::Contains("afile"));
    RunResult bad = runPenumbra("bench generators --threads 0");
    CHECK(bad.exitCode == 1);
    CHECK_THAT(bad.err, Catch::Contains("--threads"));
}
