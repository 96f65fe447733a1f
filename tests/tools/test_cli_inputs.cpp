// Classes of bad input that once crashed, hung or passed silently, each answered by one clean
// line and exit 1: nesting deep enough to overflow the stack (scene JSON, glTF extras, scatter
// sources), numbers beyond double range, special files as inputs, binary files as OBJ, an entry
// type that contradicts the file, counts no bake can stream, and values out of range.

#include "CliRunner.h"

#include "stream/util/JsonText.h"
#include "stream/util/Npy.h"

#include <catch2/catch.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <sys/stat.h>
#include <sys/sysmacros.h>

using namespace penumbra;
using namespace penumbra::test;

namespace {

const char* kScene = R"({
  "geometry": [{"type": "obj", "path": "quad.obj"}],
  "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 16, "sample_sets": 2}],
  "receivers": {"type": "camera", "eye": [0,3,3], "target": [0,0,0], "width": 16, "height": 12},
  "output": "out/x.exr"})";

const char* kQuad = "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 2 3 4\n";

void write(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

/// `[[[...0...]]]`, @p depth levels deep, as JSON text.
std::string nested(int depth) { return std::string(size_t(depth), '[') + "0" + std::string(size_t(depth), ']'); }

/// An OBJ of separate triangle strips of at least @p bytes; @p strips gets their count.
std::string stripsObj(size_t bytes, int& strips) {
    std::string text;
    for (strips = 0; text.size() < bytes; ++strips)
        text += fmt::format("v {} 0 -1\nv {} 0 1\nv {} 0.5 0\nf -3 -2 -1\n", strips * 1e-3, strips * 1e-3, strips * 1e-3 + 5e-4);
    return text;
}

/// A command that failed in a shown pass: the phase ends without "done", with the one error line.
void requireFailedPass(const RunResult& r) {
    CHECK(r.exitCode == 1);
    CHECK(r.err.find("done in") == std::string::npos);
    CHECK_THAT(r.err, Catch::Contains("strips.obj:") && Catch::EndsWith("\n"));
}

/// A scene in @p dir with the quad, and the bake's result.
RunResult bake(const ScratchDir& dir, const std::string& sceneText, const std::string& flags = "-q") {
    write(dir / "quad.obj", kQuad);
    write(dir / "scene.json", sceneText);
    return runPenumbra("bake " + (dir / "scene.json") + " " + flags);
}

/// The scene with @p key of @p path (a JSON pointer) replaced by raw JSON text @p raw.
std::string withRaw(const std::string& pointer, const std::string& raw) {
    nlohmann::json s = nlohmann::json::parse(kScene);
    s[nlohmann::json::json_pointer(pointer)] = "@RAW@";
    std::string text = s.dump();
    return text.replace(text.find("\"@RAW@\""), 7, raw);
}

}  // namespace

TEST_CASE("deep nesting anywhere in a scene is refused before anything recurses", "[cli][inputs]") {
    ScratchDir dir("nesting");
    for (const char* where : {"/geometry/0/cells", "/receivers/eye", "/lights/0/center", "/bake"}) {
        INFO(where);
        requireCleanError(bake(dir, withRaw(where, nested(10000))), "JSON nests deeper than 64 levels");
        requireCleanError(bake(dir, withRaw(where, nested(1000000))), "JSON nests deeper than 64 levels");
    }
    // Within the limit the nesting is an ordinary type error naming the key.
    requireCleanError(bake(dir, withRaw("/geometry/0/cells", nested(40))), "geometry[0].cells");
    // Braces inside strings do not count.
    CHECK_NOTHROW(checkJsonDepth("[\"" + std::string(1000, '[') + "\"]", "x"));
}

TEST_CASE("scatter sources nest at most 16 deep", "[cli][inputs]") {
    ScratchDir dir("scatter-nesting");
    nlohmann::json entry = {{"type", "obj"}, {"path", "quad.obj"}};
    for (int i = 0; i < 20; ++i) entry = {{"type", "scatter"}, {"count", 1}, {"source", entry}};
    nlohmann::json s = nlohmann::json::parse(kScene);
    s["geometry"] = listOf(entry);
    requireCleanError(bake(dir, s.dump()), "scatter sources nest more than 16 deep");
}

TEST_CASE("glTF and GLB extras nested 20,000 deep are refused by the reader and by bake", "[cli][inputs]") {
    ScratchDir dir("gltf-nesting");
    const std::string json = R"({"asset":{"version":"2.0","extras":)" + nested(20000) + "}}";
    write(dir / "deep.gltf", json);
    std::string glb = "glTF";
    auto u32 = [](uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
    std::string chunk = json + std::string((4 - json.size() % 4) % 4, ' ');
    glb += u32(2) + u32(uint32_t(12 + 8 + chunk.size())) + u32(uint32_t(chunk.size())) + u32(0x4E4F534Au) + chunk;
    write(dir / "deep.glb", glb);
    for (const char* file : {"deep.gltf", "deep.glb"}) {
        requireCleanError(runPenumbra("info " + (dir / file)), "JSON nests deeper than 64 levels");
        nlohmann::json s = nlohmann::json::parse(kScene);
        s["geometry"] = listOf({{"type", "gltf"}, {"path", file}});
        requireCleanError(bake(dir, s.dump()), "JSON nests deeper than 64 levels");
    }
}

TEST_CASE("numbers beyond double range are errors naming the key, never internal errors", "[cli][inputs]") {
    ScratchDir dir("overflow");
    RunResult r = bake(dir, withRaw("/lights/0/power", "1e309"));
    requireCleanError(r, "lights[0].power: number overflow parsing '1e309'");
    requireCleanError(bake(dir, withRaw("/receivers/eye/1", "-1e400")), "receivers.eye[1]: number overflow");
    // A seed takes the whole unsigned range, exactly.
    r = bake(dir, withRaw("/bake", R"({"seed": 18446744073709551615})"));
    INFO(r.err);
    CHECK(r.exitCode == 0);
    requireCleanError(bake(dir, withRaw("/bake", R"({"seed": -1})")), "bake.seed: must be in 0..18446744073709551615");
    requireCleanError(bake(dir, withRaw("/bake", R"({"group_size": 18446744073709551615})")), "bake.group_size: must be in 1..64");
}

TEST_CASE("FIFOs and devices given as inputs are refused at once", "[cli][inputs]") {
    ScratchDir dir("special-inputs");
    REQUIRE(::mkfifo((dir / "fifo.obj").c_str(), 0600) == 0);
    REQUIRE(::mkfifo((dir / "fifo.npy").c_str(), 0600) == 0);
    REQUIRE(::mkfifo((dir / "fifo.csv").c_str(), 0600) == 0);
    REQUIRE(::mkfifo((dir / "fifo.json").c_str(), 0600) == 0);
    const bool devices = ::mknod((dir / "zero.obj").c_str(), S_IFCHR | 0600, makedev(1, 5)) == 0;
    const std::string timeout = "timeout 20";
    requireCleanError(runPenumbra("info " + (dir / "fifo.obj"), timeout), "fifo.obj: is a FIFO, not a regular file");
    requireCleanError(runPenumbra("bake " + (dir / "fifo.json"), timeout), "fifo.json: is a FIFO, not a regular file");
    for (const char* points : {"fifo.npy", "fifo.csv"}) {
        nlohmann::json s = nlohmann::json::parse(kScene);
        s["receivers"] = {{"type", "points"}, {"path", points}};
        write(dir / "quad.obj", kQuad);
        write(dir / "points.json", s.dump());
        requireCleanError(runPenumbra("bake " + (dir / "points.json") + " -q", timeout),
                          std::string(points) + ": is a FIFO, not a regular file");
    }
    if (devices) {
        nlohmann::json s = nlohmann::json::parse(kScene);
        s["geometry"] = listOf({{"type", "obj"}, {"path", "zero.obj"}});
        requireCleanError(bake(dir, s.dump()), "zero.obj: is a character device, not a regular file");
    }
}

TEST_CASE("binary files, UTF-16 and images are not OBJ text", "[cli][inputs]") {
    ScratchDir dir("binary-obj");
    static const char random[] = "v 0 0 0\n\x01\x02\0\xff garbage", utf16[] = "\xff\xfev\0 \0" "0\0",
                      exr[] = "\x76\x2f\x31\x01\x02\0\0\0channels\0chlist\0";  // the start of an EXR header
    write(dir / "random.obj", std::string(random, sizeof random - 1));
    write(dir / "utf16.obj", std::string(utf16, sizeof utf16 - 1));
    write(dir / "image.obj", std::string(exr, sizeof exr - 1));
    requireCleanError(runPenumbra("info " + (dir / "random.obj")), "random.obj: is binary, not OBJ text");
    requireCleanError(runPenumbra("info " + (dir / "utf16.obj")), "utf16.obj: is UTF-16 text");
    requireCleanError(runPenumbra("info " + (dir / "image.obj")), "image.obj: is binary, not OBJ text");
    // Text without a single face line reads as no triangles, and says so.
    write(dir / "prose.obj", "This is not a mesh.\nJust words.\n");
    RunResult r = runPenumbra("info " + (dir / "prose.obj"));
    CHECK(r.exitCode == 0);
    CHECK_THAT(r.err, Catch::Contains("warning: " + (dir / "prose.obj") + ": no face line was understood"));
    write(dir / "empty.obj", "");
    RunResult empty = runPenumbra("info " + (dir / "empty.obj"));
    CHECK(empty.exitCode == 0);
    CHECK_THAT(empty.err, Catch::Contains("warning: " + (dir / "empty.obj") + ": is empty (0 triangles)"));
    // A CSV with a NUL byte is binary too.
    static const char csv[] = "0,0,0,0,1,0\n\0\0\n";
    write(dir / "pts.csv", std::string(csv, sizeof csv - 1));
    nlohmann::json s = nlohmann::json::parse(kScene);
    s["receivers"] = {{"type", "points"}, {"path", "pts.csv"}};
    requireCleanError(bake(dir, s.dump()), "pts.csv:2: is binary, not CSV text");
}

TEST_CASE("a geometry entry's type chooses its reader and must not contradict the file", "[cli][inputs]") {
    ScratchDir dir("entry-type");
    write(dir / "quad.txt", kQuad);
    nlohmann::json s = nlohmann::json::parse(kScene);
    s["geometry"] = listOf({{"type", "obj"}, {"path", "quad.txt"}});
    RunResult r = bake(dir, s.dump(), "-q --stats " + (dir / "stats.json"));
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    CHECK(nlohmann::json::parse(slurp(dir / "stats.json"))["counters"]["triangles_read"] == 2);
    s["geometry"] = listOf({{"type", "glb"}, {"path", "quad.obj"}});
    requireCleanError(bake(dir, s.dump()), "geometry[0].type: \"glb\" does not match the file");
}

TEST_CASE("counts no bake can stream are refused at their key", "[cli][inputs]") {
    ScratchDir dir("counts");
    for (const char* type : {"grass", "flowers", "forest", "scatter"}) {
        nlohmann::json entry = {{"type", type}, {"count", 1e15}};
        if (std::string(type) == "scatter") entry["source"] = {{"type", "obj"}, {"path", "quad.obj"}};
        nlohmann::json s = nlohmann::json::parse(kScene);
        s["geometry"] = listOf(entry);
        INFO(type);
        requireCleanError(bake(dir, s.dump()), "geometry[0].count: must be in 0..");
    }
    nlohmann::json s = nlohmann::json::parse(kScene);
    s["geometry"] = listOf({{"type", "grass"}, {"density", 1e300}});
    requireCleanError(bake(dir, s.dump()), "geometry[0].density");
}

TEST_CASE("out-of-range command-line values are errors, not silent defaults", "[cli][inputs]") {
    ScratchDir dir("cli-values");
    write(dir / "quad.obj", kQuad);
    write(dir / "scene.json", kScene);
    const std::string scene = "bake " + (dir / "scene.json") + " -q ";
    requireCleanError(runPenumbra(scene + "--threads 2000000000"), "--threads: must be in 0..4096");
    requireCleanError(runPenumbra(scene + "-o ''"), "--output: must not be empty");
    requireCleanError(runPenumbra(scene + "--tmp ''"), "--tmp: must not be empty");
    requireCleanError(runPenumbra(scene + "--stats ''"), "--stats: must not be empty");
    requireCleanError(runPenumbra(scene + "--memory-budget 0"), "--memory-budget: must be more than 0");
    RunResult gen = runPenumbra("bench generators --triangles -5");
    CHECK(gen.exitCode != 0);
    CHECK(lineCount(gen.err) <= 2);
    requireCleanError(runPenumbra("generate " + (dir / "scene.json") + " -o " + (dir / "g.ptri") + " --threads 99999"),
                      "--threads: must be in 0..4096");
}

TEST_CASE("scene numbers out of range are errors naming the key", "[cli][inputs]") {
    ScratchDir dir("scene-numbers");
    requireCleanError(bake(dir, withRaw("/bake", R"({"epsilon": 1e308})")), "bake.epsilon: must be in 0..0.1");
    // Masks hold a bit per sample of every light: their total is bounded, and so are the positions.
    nlohmann::json s = nlohmann::json::parse(kScene);
    for (int i = 0; i < 17; ++i) s["lights"][i] = s["lights"][0], s["lights"][i]["samples"] = 65536;
    requireCleanError(bake(dir, s.dump()), "lights: 1048576 + 65536 = 1114112 light samples in all, more than the limit");
    s["lights"] = nlohmann::json::array({s["lights"][0], s["lights"][0], s["lights"][0], s["lights"][0], s["lights"][0]});
    s["lights"][0]["sample_sets"] = 256;
    requireCleanError(bake(dir, s.dump()), "lights: 327680 x 256 = 83886080 sample positions (samples x sets), more than");
    // Forest variants are kept in memory; a grid's coordinates must stay finite as floats.
    s = nlohmann::json::parse(kScene);
    s["geometry"] = listOf({{"type", "forest"}, {"count", 1}, {"depth", 8}, {"branches", 3}, {"sides", 8}, {"variants", 64}});
    requireCleanError(bake(dir, s.dump()), "geometry[0].variants:");
    s["geometry"] = listOf({{"type", "grid"}, {"size", 1e300}});
    requireCleanError(bake(dir, s.dump()), "geometry[0].size: must be in (0, 1e9]");
    s["geometry"] = listOf({{"type", "grid"}, {"spacing", 1e8}, {"levels", 1000}});
    requireCleanError(bake(dir, s.dump()), "geometry[0].spacing");
}

TEST_CASE("requests that cannot fit in memory are refused before any work, with the numbers", "[cli][inputs]") {
    ScratchDir dir("no-fit");
    // A 60000 x 60000 camera's z-buffer alone is hundreds of GiB, more than any test machine has.
    nlohmann::json s = nlohmann::json::parse(kScene);
    s["receivers"]["width"] = 60000, s["receivers"]["height"] = 60000;
    RunResult r = bake(dir, s.dump(), "");
    requireCleanError(r, "the scan pass needs at least ");
    CHECK_THAT(r.err, Catch::Contains("of memory, but this machine has"));
    CHECK(r.err.find("[scan]") == std::string::npos);
}

TEST_CASE("a large OBJ's check pass on opening is a phase of its own on stderr, silent with -q", "[cli][inputs][progress]") {
    ScratchDir dir("obj-check-progress");
    // Files from 32 MiB on show the pass (smaller ones take under a quarter second); a 20 GB file
    // spent minutes here in silence.
    int strips = 0;
    const std::string text = stripsObj(33u << 20, strips);
    write(dir / "strips.obj", text);
    nlohmann::json s = nlohmann::json::parse(kScene);
    s["geometry"][0]["path"] = "strips.obj";
    RunResult loud = bake(dir, s.dump(), "");
    INFO(loud.err);
    REQUIRE(loud.exitCode == 0);
    const std::string done = fmt::format("[check strips.obj] 100.0% ({0}/{0}) done in ", text.size());
    CHECK_THAT(loud.err, Catch::Contains(done));
    CHECK(loud.err.find(done) < loud.err.find("[scan]"));  // before the scan pass, which it delays
    RunResult quiet = bake(dir, s.dump(), "-q");
    CHECK(quiet.exitCode == 0);
    CHECK(quiet.err.empty());
    // A small file's pass is not shown.
    CHECK(bake(dir, kScene, "").err.find("[check") == std::string::npos);
    // A file that fails its check ends the phase without a "done" line, with the one error line.
    write(dir / "strips.obj", text + "f 1 2 99999999\n");
    requireFailedPass(bake(dir, s.dump(), ""));
}

TEST_CASE("info, convert and generate show their passes over a large input as phases, silent with -q", "[cli][inputs][progress]") {
    ScratchDir dir("tool-progress");
    int strips = 0;
    const std::string text = stripsObj(33u << 20, strips);
    write(dir / "strips.obj", text);
    const std::string check = fmt::format("[check strips.obj] 100.0% ({0}/{0}) done in ", text.size());
    // info: the check pass on opening, then the pass over the triangles; stdout is the result alone.
    RunResult info = runPenumbra("info " + (dir / "strips.obj"));
    INFO(info.err);
    REQUIRE(info.exitCode == 0);
    CHECK_THAT(info.out, Catch::StartsWith(fmt::format("triangles {}\n", strips)));
    CHECK_THAT(info.err, Catch::Contains(check));
    CHECK(info.err.find(check) < info.err.find(fmt::format("[read strips.obj] 100.0% ({0}/{0}) done in ", strips)));
    // convert: the streamed pass, or the indexed meshes' load for glTF.
    RunResult ptri = runPenumbra("convert " + (dir / "strips.obj") + " " + (dir / "strips.ptri"));
    CHECK(ptri.exitCode == 0);
    CHECK_THAT(ptri.err, Catch::Contains(check) && Catch::Contains(fmt::format("[convert strips.obj] 100.0% ({0}/{0}) done in ", strips)));
    RunResult glb = runPenumbra("convert " + (dir / "strips.obj") + " " + (dir / "strips.glb"));
    CHECK(glb.exitCode == 0);
    CHECK_THAT(glb.err, Catch::Contains(fmt::format("[load strips.obj] 100.0% ({0}/{0}) done in ", text.size())));
    // generate: the scene's one pass, with its summary line after it.
    nlohmann::json scene = nlohmann::json::parse(kScene);
    scene["geometry"][0]["path"] = "strips.obj";
    write(dir / "scene.json", scene.dump());
    RunResult generated = runPenumbra("generate " + (dir / "scene.json") + " -o " + (dir / "all.ptri"));
    INFO(generated.err);
    CHECK(generated.exitCode == 0);
    CHECK_THAT(generated.err, Catch::Contains(fmt::format("[generate] 100.0% ({0}/{0}) done in ", strips)) &&
                                  Catch::Contains(fmt::format("penumbra: {} triangles -> ", strips)));
    // -q: nothing on stderr, the same results.
    for (const std::string& quiet : {"info -q " + (dir / "strips.obj"), "convert -q " + (dir / "strips.obj") + " " + (dir / "q.ptri"),
                                     "convert -q " + (dir / "strips.obj") + " " + (dir / "q.glb"),
                                     "generate -q " + (dir / "scene.json") + " -o " + (dir / "q-all.ptri")}) {
        RunResult r = runPenumbra(quiet);
        INFO(quiet);
        CHECK(r.exitCode == 0);
        CHECK(r.err.empty());
    }
    CHECK(runPenumbra("info -q " + (dir / "q.ptri")).out == runPenumbra("info -q " + (dir / "strips.ptri")).out);
    // A file that fails in the pass ends it without "done", with the one error line.
    write(dir / "strips.obj", text + "f 1 2 99999999\n");
    for (const std::string& args : {"info " + (dir / "strips.obj"), "convert " + (dir / "strips.obj") + " " + (dir / "bad.glb")}) {
        RunResult bad = runPenumbra(args);
        INFO(args << "\n" << bad.err);
        requireFailedPass(bad);
    }
}

TEST_CASE("convert from glTF shows its pass and says when cut-out materials become plain surfaces", "[cli][inputs][progress]") {
    // glTF to glTF showed nothing, and every output lost the tree's MASK leaf cards silently.
    ScratchDir dir("convert-gltf-progress");
    REQUIRE(runPenumbra("make-example gltf-tree -o " + (dir / "tree.glb")).exitCode == 0);
    const std::string warning = "tree.glb: 280 triangle(s) with cut-out or blended materials (alphaMode MASK or BLEND) are written as plain surfaces";
    for (const char* out : {"copy.glb", "copy.gltf", "copy.ptri", "copy.obj"}) {
        const RunResult r = runPenumbra("convert " + (dir / "tree.glb") + " " + (dir / out));
        INFO(out << "\n" << r.err);
        REQUIRE(r.exitCode == 0);
        CHECK_THAT(r.err, Catch::Contains(warning) && Catch::Contains("[convert tree.glb] 100.0% (292/292) done in "));
        const RunResult quiet = runPenumbra("convert -q " + (dir / "tree.glb") + " " + (dir / out));
        CHECK_THAT(quiet.err, Catch::Contains(warning) && !Catch::Contains("[convert"));
    }
    const RunResult opaque = runPenumbra("convert " + (dir / "copy.glb") + " " + (dir / "again.glb"));  // materials gone: nothing to say
    CHECK(opaque.exitCode == 0);
    CHECK_THAT(opaque.err, !Catch::Contains("warning"));
}

TEST_CASE("a bake shows the load of a large OBJ that a lightmap's receivers come from", "[cli][inputs][progress]") {
    ScratchDir dir("lightmap-load-progress");
    std::string text;
    while (text.size() < (33u << 20)) text += "# a comment line that pads the file past the size from which its passes are shown\n";
    text += "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n";
    write(dir / "padded.obj", text);
    nlohmann::json s = nlohmann::json::parse(kScene);
    s["geometry"][0]["path"] = "padded.obj";
    s["receivers"] = {{"type", "lightmap"}, {"meshes", {0}}, {"resolution", 16}};
    write(dir / "scene.json", s.dump());
    RunResult loud = runPenumbra("bake " + (dir / "scene.json"));
    INFO(loud.err);
    REQUIRE(loud.exitCode == 0);
    const std::string load = fmt::format("[load padded.obj] 100.0% ({0}/{0}) done in ", text.size());
    CHECK_THAT(loud.err, Catch::Contains(load) && Catch::Contains("[check padded.obj] 100.0%"));
    CHECK(loud.err.find(load) < loud.err.find("[scan]"));
    RunResult quiet = runPenumbra("bake -q " + (dir / "scene.json"));
    CHECK(quiet.exitCode == 0);
    CHECK(quiet.err.empty());
}
