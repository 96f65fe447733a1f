// The other methods end to end (ssv, penumbra-map, hh, and the existing ones): the same output
// bytes for one and two threads, ssv equal to hpc up to ties, and clean refusals.

#include "CliRunner.h"

#include "stream/util/Npy.h"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <csignal>
#include <filesystem>

#include <unistd.h>

using namespace penumbra;
using namespace penumbra::test;

namespace {

const char* kCameraScene = R"({
  "geometry": [{"type": "grid", "cells": 4, "levels": 2, "size": 2, "floor_size": 5}],
  "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 64, "sample_sets": 4}],
  "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0.5,0], "width": 48, "height": 36},
  "output": "out/camera.exr"})";

/// The lightmap example's room and blockers at a small resolution, copied beside the scene (scene
/// paths stay in the scene's directory).
std::string lightmapScene(const ScratchDir& dir) {
    for (const char* name : {"room.obj", "room-blockers.obj"})
        std::filesystem::copy_file(std::string(PENUMBRA_SOURCE_DIR) + "/examples/" + name, dir / name);
    return R"({"geometry": [{"type": "obj", "path": "room.obj"}, {"type": "obj", "path": "room-blockers.obj"}],
      "lights": [{"type": "rect", "center": [2.2, 4.0, 1.8], "u": [1.5, 0, 0], "v": [0, 0, 1.5], "samples": 64, "sample_sets": 4}],
      "receivers": {"type": "lightmap", "meshes": [0], "resolution": 48, "padding": 2},
      "output": "out/lightmap.exr"})";
}

void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

/// Bakes @p scene with @p method on 1 and 2 threads and requires identical output files.
void requireThreadIndependent(const ScratchDir& dir, const std::string& scene, const std::string& method,
                              const std::vector<std::string>& outputs) {
    for (int threads : {1, 2}) {
        const std::string out = dir / fmt::format("t{}-{}", threads, method);
        std::filesystem::create_directories(out);  // -o names an existing folder
        RunResult r = runPenumbra("bake " + scene + " -q --method " + method + " --threads " + std::to_string(threads) +
                                  " -o " + out + "/out.exr --visibility " + out + "/v.npy");
        INFO(method << ", " << threads << " threads: " << r.err);
        REQUIRE(r.exitCode == 0);
    }
    for (const std::string& name : outputs) {
        INFO(method << ": " << name);
        const std::string a = slurp(dir / ("t1-" + method + "/" + name)), b = slurp(dir / ("t2-" + method + "/" + name));
        CHECK(!a.empty());
        CHECK(a == b);
    }
}

}  // namespace

TEST_CASE("every method gives the same output bytes on one and two threads", "[cli][methods]") {
    ScratchDir dir("methods");
    write(dir / "camera.json", kCameraScene);
    write(dir / "lightmap.json", lightmapScene(dir));
    for (const char* method : {"hpc", "reference", "embree", "ssv", "penumbra-map"})
        requireThreadIndependent(dir, dir / "camera.json", method, {"out.exr", "out.png", "v.npy"});
    for (const char* method : {"hpc", "hh"})
        requireThreadIndependent(dir, dir / "lightmap.json", method, {"out-room.exr", "out-room.png", "v.npy"});
}

TEST_CASE("ssv bakes the masks hpc bakes up to ties, and hh and penumbra-map refuse what they cannot do", "[cli][methods]") {
    ScratchDir dir("methods");
    write(dir / "camera.json", kCameraScene);
    for (const char* method : {"hpc", "ssv"}) {
        RunResult r = runPenumbra("bake " + (dir / "camera.json") + " -q --method " + method + " -o " + (dir / method) +
                                  ".exr --dump " + (dir / method) + " --stats " + (dir / method) + ".json");
        INFO(r.err);
        REQUIRE(r.exitCode == 0);
    }
    RunResult cmp = runPenumbra("compare " + (dir / "hpc") + " " + (dir / "ssv") + " --scene " + (dir / "camera.json"));
    INFO(cmp.out);
    CHECK(cmp.exitCode == 0);
    CHECK_THAT(slurp(dir / "ssv.json"), Catch::Contains("\"edges_per_frustum\"") && Catch::Contains("\"kd_tree\""));

    RunResult hh = runPenumbra("bake " + (dir / "camera.json") + " -q --method hh");
    CHECK(hh.exitCode == 1);
    CHECK(lineCount(hh.err) == 1);
    CHECK_THAT(hh.err, Catch::StartsWith("penumbra: error: --method hh: applies to lightmap receivers only"));
    RunResult dump = runPenumbra("bake " + (dir / "camera.json") + " -q --method penumbra-map --dump " + (dir / "pm"));
    CHECK(dump.exitCode == 1);
    CHECK(lineCount(dump.err) == 1);
    CHECK_THAT(dump.err, Catch::StartsWith("penumbra: error: --dump: --method penumbra-map"));
    CHECK_FALSE(std::filesystem::exists(dir / "pm"));

    RunResult pm = runPenumbra("bake " + (dir / "camera.json") + " -q --method penumbra-map --penumbra-map-resolution 256 -o " +
                               (dir / "pm.exr") + " --visibility " + (dir / "pm.npy"));
    REQUIRE(pm.exitCode == 0);
    const NpyArray v = readNpy(dir / "pm.npy");
    CHECK(v.dtype == "<f4");
    REQUIRE(v.shape.size() == 1);
    CHECK(v.shape[0] == readNpy(dir / "hpc/receivers.npy").shape[0]);
}

TEST_CASE("another method's options are named as ignored, and the method's own are not", "[cli][methods]") {
    // --embree-filter off with hpc was taken without a word.
    ScratchDir dir("methods-options");
    write(dir / "camera.json", kCameraScene);
    const std::string bake = "bake " + dir / "camera.json" + " -q --threads 1";
    RunResult hpc = runPenumbra(bake + " --embree-filter off --penumbra-map-taps 5");
    INFO(hpc.err);
    REQUIRE(hpc.exitCode == 0);
    CHECK_THAT(hpc.err, Catch::Contains("penumbra: warning: --embree-filter applies to --method embree only; --method hpc ignores it"));
    CHECK_THAT(hpc.err, Catch::Contains("penumbra: warning: --penumbra-map-taps applies to --method penumbra-map only; --method hpc "
                                        "ignores it"));
    RunResult own = runPenumbra(bake + " --method penumbra-map --penumbra-map-taps 5 --penumbra-map-lookup wyman-hansen");
    INFO(own.err);
    REQUIRE(own.exitCode == 0);
    CHECK(own.err.find("warning") == std::string::npos);
}

TEST_CASE("a method's own scene keys are read by the method whichever method bakes", "[cli][methods]") {
    ScratchDir dir("methods");
    auto scene = [&](const std::string& bake) {
        std::string text = kCameraScene;
        text.insert(text.rfind('}'), ", \"bake\": {" + bake + "}");
        write(dir / "keys.json", text);
        return dir / "keys.json";
    };
    // Accepted by every method (hpc ignores them), so a scene tuned for a preview still bakes exactly.
    RunResult ok = runPenumbra("bake " + scene("\"penumbra_map_resolution\": 64, \"penumbra_map_bias\": 2") + " -q -o " +
                               (dir / "keys.exr"));
    INFO(ok.err);
    CHECK(ok.exitCode == 0);
    requireCleanError(runPenumbra("bake " + scene("\"penumbra_map_resolution\": 8") + " -q"), "bake.penumbra_map_resolution");
    requireCleanError(runPenumbra("bake " + scene("\"penumbra_map_bias\": -1") + " -q --method penumbra-map"),
                      "bake.penumbra_map_bias: must be in 0..1000000, got -1");
    requireCleanError(runPenumbra("bake " + scene("\"penumbra_map_bias\": 2e6") + " -q --method penumbra-map"),
                      "bake.penumbra_map_bias: must be in 0..1000000, got 2000000");  // as --penumbra-map-bias
    requireCleanError(runPenumbra("bake " + scene("\"penumbra_map_resolutions\": 64") + " -q"), "penumbra_map_resolutions");
    requireCleanError(runPenumbra("bake " + scene("\"penumbra_map_lookup\": \"pcss\"") + " -q --method penumbra-map"),
                      "bake.penumbra_map_lookup: must be \"backprojection\" or \"wyman-hansen\"");
    requireCleanError(runPenumbra("bake " + scene("\"penumbra_map_taps\": 9") + " -q --method penumbra-map"), "bake.penumbra_map_taps");
    // Fewer taps read a coarser level: a valid bake whose stats say so.
    RunResult taps = runPenumbra("bake " + scene("\"penumbra_map_taps\": 1") + " -q --method penumbra-map --stats " +
                                 (dir / "taps.json") + " -o " + (dir / "taps.exr"));
    INFO(taps.err);
    REQUIRE(taps.exitCode == 0);
    CHECK(nlohmann::json::parse(slurp(dir / "taps.json"))["penumbra-map"]["taps"] == 1);
    CHECK(runPenumbra("bake " + scene("") + " -q --method penumbra-map --penumbra-map-taps 0").exitCode != 0);
}

TEST_CASE("bench methods --render writes the Markdown of an earlier result, with whole-bake and CPU ratios", "[cli][methods]") {
    ScratchDir dir("methods");
    auto method = [](double time, double bake, double cpu) {
        return fmt::format(R"({{"time_s": {}, "bake_total_s": {}, "process_cpu_s": {}, "peak_rss_bytes": 1048576{}}})", time, bake, cpu,
                           time == 40 ? "" : R"(, "speedup_vs_hpc": 8, "error_vs_hpc": {"mean_abs_dv": 0.02, "max_abs_dv": 0.5, "fraction_above_0_1": 0.01})");
    };
    write(dir / "result.json",
          fmt::format(R"({{"command": "penumbra bench methods", "date": "2026-12-02 03:00 UTC", "scale": 1, "threads": 1, "repeat": 1,
            "load_average_start": 1, "load_average_end": 1, "elapsed_s": 10,
            "machine": {{"cpu": "cpu", "cores": 2, "ram_bytes": 1073741824, "os": "os", "compiler": "cc", "commit": "abc"}},
            "rows": [{{"scene": "grids", "nominal": "1280x960", "width": 1280, "height": 960,
                       "methods": {{"hpc": {}, "penumbra-map": {}}}}}], "hh": []}})",
                      method(40, 50, 20), method(5, 10, 4)));
    write(dir / "BENCH.md", "# Benchmarks\n");
    RunResult r = runPenumbra("bench methods --render " + (dir / "result.json") + " --markdown " + (dir / "BENCH.md"));
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    // Cast 40 / 5, whole bake 50 / 10, CPU 20 / 4: the target needs both wall-time ratios.
    CHECK_THAT(r.out, Catch::Contains("| grids | 1280×960 | penumbra-map | 5.00 | 8.00× | 10.00 | 5.00× | 4.00 | 5.00× |"));
    CHECK_THAT(r.out, Catch::Contains("| 8.0× / 5.0× / 5.0× | **not met** |"));
    CHECK_THAT(r.out, Catch::Contains("| penumbra-map mean abs dV < 0.05 on grids 1280x960 | 0.0200 | met |"));
    CHECK_THAT(slurp(dir / "BENCH.md"), Catch::Contains("# Benchmarks") && Catch::Contains("penumbra bench methods: begin"));
    // Sections only for the methods the run had: no ssv, no hh.
    CHECK(r.out.find("### ssv") == std::string::npos);
    CHECK(r.out.find("### hh") == std::string::npos);
    write(dir / "bad.json", "{\"rows\": 3}");
    requireCleanError(runPenumbra("bench methods --render " + (dir / "bad.json")), "--render");
}

TEST_CASE("bench methods reads a scene's files where the scene lives, and compares an antialiased view on its first pass",
          "[cli][methods]") {
    // The bench bakes a resized copy of each scene in its own temporary directory: the scene's
    // relative paths must still reach its files. With antialiasing the second pass refines where
    // each method's own V changes, so the receivers differ past the first pass.
    ScratchDir dir("bench-paths");
    std::filesystem::create_directories(dir / "scenes");
    std::filesystem::copy_file(std::string(PENUMBRA_SOURCE_DIR) + "/examples/room-blockers.obj", dir / "scenes/blockers.obj");
    write(dir / "scenes/aa.json", R"({
      "geometry": [{"type": "obj", "path": "blockers.obj"}, {"type": "grid", "cells": 4, "levels": 1, "size": 2, "floor_size": 8}],
      "lights": [{"type": "rect", "center": [1,5,1], "u": [1,0,0], "v": [0,0,1], "samples": 64, "sample_sets": 2}],
      "receivers": {"type": "camera", "eye": [0,5,6], "target": [0,0.5,0], "width": 64, "height": 48,
                    "antialias": {"threshold": 0.1, "samples": 4}},
      "output": "out/aa.exr"})");
    RunResult r = runPenumbra("bench methods -q --examples " + (dir / "scenes") + " --scenes aa --sizes 64x48 --methods hpc,penumbra-map,penumbra-map:wyman-hansen" +
                              " --threads 1 --no-compare --tmp " + dir.path.string() + " --json " + (dir / "result.json"));
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    const nlohmann::json result = nlohmann::json::parse(slurp(dir / "result.json"));
    const nlohmann::json& row = result.at("rows").at(0).at("methods");
    REQUIRE(row.at("hpc").contains("time_s"));
    CHECK(row.size() == 3);  // naming hpc, which every row runs, adds no row of its own
    const nlohmann::json& pm = row.at("penumbra-map");
    INFO(pm.dump());
    REQUIRE(pm.at("error_vs_hpc").contains("mean_abs_dv"));
    const uint64_t firstPass = row.at("hpc").at("first_pass_receivers").get<uint64_t>();
    CHECK(firstPass > 1000u);  // a pixel per receiver where the view meets the floor or the room
    CHECK(firstPass <= 64u * 48u);
    CHECK(row.at("hpc").at("receivers").get<uint64_t>() > firstPass);  // the antialiasing pass added receivers
    CHECK(pm.at("first_pass_receivers").get<uint64_t>() == firstPass);
    CHECK(pm.at("error_vs_hpc").at("compared_receivers").get<uint64_t>() == firstPass);
    CHECK(pm.at("error_vs_hpc").at("mean_abs_dv").get<double>() < 0.2);
    // The variant bakes the preview with the paper's lookup, in a row of its own.
    const nlohmann::json& wh = row.at("penumbra-map:wyman-hansen");
    INFO(wh.dump());
    CHECK(pm.at("penumbra-map").at("lookup") == "backprojection");
    CHECK(wh.at("penumbra-map").at("lookup") == "wyman-hansen");
    CHECK(wh.at("error_vs_hpc").at("compared_receivers").get<uint64_t>() == firstPass);
    CHECK(slurp(dir / "result.json").find("penumbra-map:wyman-hansen") != std::string::npos);
    requireCleanError(runPenumbra("bench methods -q --methods penumbra-map:soft"), "--methods");
    // One file for the JSON and the Markdown would lose the document the section goes into.
    write(dir / "doc.md", "# notes\n");
    for (const char* bench : {"methods", "table2"}) {
        RunResult same = runPenumbra(fmt::format("bench {} -q --json {} --markdown {}", bench, dir / "doc.md", dir / "./doc.md"));
        requireCleanError(same, "--markdown: names the same file as --json");
        CHECK(slurp(dir / "doc.md") == "# notes\n");
    }
    requireCleanError(runPenumbra("bench methods -q --methods ssv:fast"), "--methods");
    // A --markdown that is no Markdown file (a script named by mistake) got the section appended.
    write(dir / "notes.py", "print('x')\n");
    for (const char* bench : {"methods", "table2"}) {
        requireCleanError(runPenumbra(fmt::format("bench {} -q --markdown {}", bench, dir / "notes.py")),
                          "--markdown: " + dir / "notes.py" + ": not a Markdown file (.md)");
        CHECK(slurp(dir / "notes.py") == "print('x')\n");
    }
    // hh's scene must be a lightmap: refused before the camera rows, not in a failed row after them.
    requireCleanError(runPenumbra("bench methods -q --methods hh --lightmap grids --examples " + std::string(PENUMBRA_SOURCE_DIR) +
                                  "/examples"),
                      "--lightmap: ");
}

namespace {

/// True while some process's command line mentions @p text (a bench child baking in its folder).
bool processMentions(const std::string& text) {
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator("/proc", ec)) {
        if (!std::isdigit(static_cast<unsigned char>(e.path().filename().string()[0]))) continue;
        const std::string cmdline = slurp(e.path().string() + "/cmdline");
        if (cmdline.find(text) != std::string::npos) return true;
    }
    return false;
}

}  // namespace

TEST_CASE("bench methods: SIGTERM or SIGINT stops the child bake too, and leaves no temporary folder", "[cli][methods]") {
    for (int sig : {SIGTERM, SIGINT}) {
        ScratchDir dir("bench-signal");
        std::filesystem::create_directories(dir / "scenes");
        std::filesystem::create_directories(dir / "tmp");
        write(dir / "scenes/long.json", kCameraScene);
        // The reference at this size runs far longer than the test waits: the signal finds a child.
        const std::string args = "bench methods -q --examples " + (dir / "scenes") + " --scenes long --sizes 96x72 --methods reference " +
                                 "--repeat 50 --no-compare --threads 1 --tmp " + (dir / "tmp");
        const pid_t bench = ::fork();
        REQUIRE(bench >= 0);
        if (bench == 0) {
            ::execl("/bin/sh", "sh", "-c", ("exec " + std::string(PENUMBRA_BINARY) + " " + args + " 2>/dev/null").c_str(), nullptr);
            ::_exit(127);
        }
        // Wait (up to 60 s) until the bench has started a child bake: its stderr file exists.
        bool started = false;
        for (int i = 0; i < 600 && !started; ++i) {
            std::error_code ec;  // the bench's folder appears, and is filled, while this looks
            for (const auto& e : std::filesystem::recursive_directory_iterator(dir / "tmp", ec))
                started = started || e.path().filename() == "child.err";
            if (!started) ::usleep(100'000);
        }
        ::usleep(300'000);
        ::kill(bench, sig);
        int status = 0;
        REQUIRE(::waitpid(bench, &status, 0) == bench);
        INFO("signal " << sig);
        CHECK(started);
        REQUIRE(WIFSIGNALED(status));
        CHECK(WTERMSIG(status) == sig);
        CHECK(std::filesystem::is_empty(dir / "tmp"));
        CHECK_FALSE(processMentions((dir / "tmp").c_str()));
    }
}

TEST_CASE("penumbra-map: receivers just in front of a light see all of it when nothing is in the way", "[penumbra-map][cli]") {
    // A 1 x 1 light at height 1 facing down, no geometry, receivers 1e-4 to 1 below the light's
    // centre and one beside it. The view's axis leans towards the receivers' mean direction, and
    // the light was taken flat in the view's image plane: its near half fell behind the
    // receivers' planes (V 0.5 at 1e-4 below, 0.79 at 0.1). The light's own plane now decides.
    ScratchDir dir("pm-near-light");
    std::ofstream(dir / "near.csv") << "x,y,z,nx,ny,nz\n0,0.9999,0,0,1,0\n0,0.99,0,0,1,0\n0,0.9,0,0,1,0\n0,0.8,0,0,1,0\n"
                                       "0,0.5,0,0,1,0\n0,0,0,0,1,0\n0.4,0.9,0,0,1,0\n";
    std::ofstream(dir / "near.json") << R"({"geometry": [], "lights": [{"type": "rect", "center": [0, 1, 0], "u": [1, 0, 0],
        "v": [0, 0, 1], "samples": 256}], "receivers": {"type": "points", "path": "near.csv"}, "output": "v.npy"})";
    RunResult r = runPenumbra("bake " + (dir / "near.json") + " -q --threads 1 --method penumbra-map");
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    const NpyArray v = readNpy(dir / "v.npy");
    REQUIRE(v.shape.size() >= 1);
    REQUIRE(v.shape[0] == 7);
    const float* values = reinterpret_cast<const float*>(v.data.data());
    for (int i = 0; i < 7; ++i) {
        INFO("receiver " << i);
        CHECK(values[i] == 1.0f);
    }
}
