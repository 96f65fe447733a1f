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
        CHECK(two.err.empty());
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
