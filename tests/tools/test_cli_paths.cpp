// Paths a scene or a glTF names stay in its directory unless --allow-outside-uris; an output is
// never an input (by device and inode) and never replaces a special file; outputs of a bake
// appear together or not at all; diagnostics never change a successful bake's exit status.

#include "CliRunner.h"

#include "stream/util/SafePath.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

using namespace penumbra;
using namespace penumbra::test;
namespace fs = std::filesystem;

namespace {

const char* kQuad = "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 2 3 4\n";

nlohmann::json sceneOf(const std::string& mesh, const std::string& output = "out/x.exr") {
    return {{"geometry", listOf({{"type", "file"}, {"path", mesh}})},
            {"lights", listOf({{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}, {"samples", 16}, {"sample_sets", 2}})},
            {"receivers", {{"type", "camera"}, {"eye", {0, 3, 3}}, {"target", {0, 0, 0}}, {"width", 16}, {"height", 12}}},
            {"output", output}};
}

void write(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

/// A glTF whose only buffer (one triangle) is at @p uri.
std::string gltfWithBuffer(const std::string& uri) {
    return R"({"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"buffers":[{"uri":")" + uri + R"(","byteLength":36}],
      "bufferViews":[{"buffer":0,"byteLength":36}],
      "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,0,1]}]})";
}

void writeTriangleBuffer(const std::string& path) {
    const float v[9] = {0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(v), sizeof v);
}

}  // namespace

TEST_CASE("scene paths may not leave the scene's directory without --allow-outside-uris", "[cli][paths]") {
    ScratchDir dir("scene-paths");
    fs::create_directories(dir.path / "scenes");
    write(dir / "outside.obj", kQuad);
    write(dir / "scenes/inside.obj", kQuad);
    const std::string scene = dir / "scenes/scene.json";
    for (const std::string& mesh : {std::string("../outside.obj"), dir / "outside.obj", std::string("sub/../../outside.obj")}) {
        write(scene, sceneOf(mesh).dump());
        INFO(mesh);
        requireCleanError(runPenumbra("bake " + scene + " -q"), "geometry[0].path: \"" + mesh + "\" leaves the scene's directory");
        RunResult allowed = runPenumbra("bake " + scene + " -q --allow-outside-uris");
        INFO(allowed.err);
        CHECK(allowed.exitCode == 0);
    }
    // Absolute paths inside the directory are fine, and so is the scene's own output there.
    write(scene, sceneOf(dir / "scenes/inside.obj").dump());
    CHECK(runPenumbra("bake " + scene + " -q").exitCode == 0);
    CHECK(fs::exists(dir / "scenes/out/x.exr"));
    // A symbolic link inside that leads outside is leaving too.
    fs::create_symlink(dir / "outside.obj", dir / "scenes/link.obj");
    write(scene, sceneOf("link.obj").dump());
    requireCleanError(runPenumbra("bake " + scene + " -q"), "through a symbolic link");
    // The scene's output follows the rule; -o is the user's own choice.
    write(scene, sceneOf("inside.obj", "../escaped.exr").dump());
    requireCleanError(runPenumbra("bake " + scene + " -q"), "output: \"" + (dir / "escaped.exr") + "\" leaves the scene's directory");
    CHECK(runPenumbra("bake " + scene + " -q -o " + (dir / "chosen.exr")).exitCode == 0);
    CHECK_FALSE(fs::exists(dir / "escaped.exr"));
    CHECK(fs::exists(dir / "chosen.exr"));
}

TEST_CASE("glTF buffer URIs may not leave the model's directory, percent-encoded or not", "[cli][paths]") {
    ScratchDir dir("gltf-uris");
    fs::create_directories(dir.path / "model");
    writeTriangleBuffer(dir / "secret.bin");
    writeTriangleBuffer(dir / "model/ok.bin");
    for (const std::string& uri : {std::string("../secret.bin"), std::string("%2e%2e/secret.bin"),
                                   std::string("%2E%2E%2Fsecret.bin"), std::string("..%2fsecret.bin"), dir / "secret.bin"}) {
        write(dir / "model/m.gltf", gltfWithBuffer(uri));
        INFO(uri);
        requireCleanError(runPenumbra("info " + (dir / "model/m.gltf")), "buffers[0].uri: \"");
        requireCleanError(runPenumbra("convert " + (dir / "model/m.gltf") + " " + (dir / "out.obj")), "leaves the model's directory");
        RunResult allowed = runPenumbra("info " + (dir / "model/m.gltf") + " --allow-outside-uris");
        INFO(allowed.err);
        CHECK(allowed.exitCode == 0);
    }
    CHECK_FALSE(fs::exists(dir / "out.obj"));
    write(dir / "model/m.gltf", gltfWithBuffer("ok.bin"));
    CHECK(runPenumbra("info " + (dir / "model/m.gltf")).exitCode == 0);
    // A buffer missing beside the model is not looked for in the current directory instead.
    write(dir / "model/m.gltf", gltfWithBuffer("secret.bin"));
    requireCleanError(runPenumbra("info model/m.gltf", "cd " + dir.path.string() + " &&"),
                      "model/secret.bin: cannot open: No such file or directory (buffer 0 of model/m.gltf)");
}

TEST_CASE("a lightmap's per-mesh files are checked against the other outputs after the scan, before the cast", "[cli][paths]") {
    // They are named after the meshes the scan finds; a dump folder or stats file at one of them
    // failed only when the outputs were put in place, after the whole cast.
    ScratchDir dir("lightmap-outputs");
    write(dir / "quad.obj", kQuad);
    const nlohmann::json scene = {
        {"geometry", {{{"type", "obj"}, {"path", "quad.obj"}}}},
        {"lights", {{{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}, {"samples", 16}}}},
        {"receivers", {{"type", "lightmap"}, {"meshes", {0}}, {"uv", "generate"}, {"resolution", 32}}}};
    write(dir / "scene.json", scene.dump());
    const std::string bake = "bake " + (dir / "scene.json") + " -o " + (dir / "x.exr");
    for (const std::string& args : {" --dump " + (dir / "x-atlas.png"), " --stats " + (dir / "x-uv1.glb"),
                                    " --visibility " + (dir / "x-atlas.exr/v.npy")}) {
        INFO(args);
        RunResult r = runPenumbra(bake + args);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.err, Catch::Contains("is named for two outputs") || Catch::Contains("which is an output file of this bake"));
        CHECK_THAT(r.err, Catch::Contains("[scan]") && !Catch::Contains("[cast]"));
        for (const char* name : {"x-atlas.exr", "x-atlas.png", "x-uv1.glb"}) CHECK_FALSE(std::filesystem::exists(dir / name));
    }
    CHECK(runPenumbra(bake + " -q --stats " + (dir / "s.json")).exitCode == 0);
    for (const char* name : {"x-atlas.exr", "x-atlas.png", "x-uv1.glb", "s.json"}) CHECK(std::filesystem::exists(dir / name));
}

TEST_CASE("an output that is also an input is refused, by device and inode", "[cli][paths]") {
    ScratchDir dir("output-input");
    write(dir / "quad.obj", kQuad);
    ::link((dir / "quad.obj").c_str(), (dir / "alias.obj").c_str());
    write(dir / "scene.json", sceneOf("quad.obj").dump());
    const std::string before = slurp(dir / "quad.obj");
    requireCleanError(runPenumbra("bake " + (dir / "scene.json") + " -q -o " + (dir / "scene.json")), "is also an input");
    requireCleanError(runPenumbra("bake " + (dir / "scene.json") + " -q -o " + (dir / "alias.obj")), "is also an input");
    requireCleanError(runPenumbra("bake " + (dir / "scene.json") + " -q --stats " + (dir / "quad.obj")), "is also an input");
    requireCleanError(runPenumbra("convert " + (dir / "quad.obj") + " " + (dir / "alias.obj")), "is also an input");
    requireCleanError(runPenumbra("generate " + (dir / "scene.json") + " -o " + (dir / "alias.obj")), "is also an input");
    requireCleanError(runPenumbra("bake " + (dir / "scene.json") + " -q --stats " + (dir / "out/x.exr")), "named for two outputs");
    CHECK(slurp(dir / "quad.obj") == before);
}

TEST_CASE("two outputs of one bake never share a file, the derived ones included", "[cli][paths]") {
    ScratchDir dir("two-outputs");
    write(dir / "quad.obj", kQuad);
    write(dir / "scene.json", sceneOf("quad.obj").dump());
    const std::string bake = "bake " + (dir / "scene.json") + " -q -o " + (dir / "x.exr");
    // --visibility and --dump are checked before the bake; the camera's PNG, which the receiver
    // kind names, when the outputs are put in place. Either way nothing is written.
    for (const std::string& args : {" --visibility " + (dir / "x.exr"), " --dump " + (dir / "x.exr"), " --stats " + (dir / "x.png"),
                                    " --visibility " + (dir / "x.png"), " --dump " + (dir / "d/") + " --stats " + (dir / "d"),
                                    " --checkpoint " + (dir / "x.exr"), " --checkpoint " + (dir / "d") + " --stats " + (dir / "d")}) {
        INFO(args);
        requireCleanError(runPenumbra(bake + args), "is named for two outputs of this bake");
        for (const char* name : {"x.exr", "x.png", "d"}) CHECK_FALSE(std::filesystem::exists(dir / name));
    }
    // A dump folder, or the folder of the stats, at the camera's PNG, and a folder already there:
    // refused before the bake, with nothing written (the EXR was replaced, then the bake failed).
    for (const std::string& args : {" --dump " + (dir / "x.png"), " --stats " + (dir / "x.png/s.json"),
                                    " --visibility " + (dir / "x.png/v.npy")}) {
        INFO(args);
        RunResult r = runPenumbra(bake + args);
        requireCleanError(r, "x.png");
        CHECK_THAT(r.err, Catch::Contains("is named for two outputs") || Catch::Contains("which is an output file of this bake"));
        for (const char* name : {"x.exr", "x.png"}) CHECK_FALSE(std::filesystem::exists(dir / name));
    }
    std::filesystem::create_directory(dir / "x.png");
    requireCleanError(runPenumbra(bake), "x.png: is a directory");
    CHECK_FALSE(std::filesystem::exists(dir / "x.exr"));
    std::filesystem::remove(dir / "x.png");
    // Other spellings of one file: through "." and "..", or through a link to the folder (the
    // stats replaced the EXR, exit 0).
    std::filesystem::create_directory(dir / "sub");
    std::filesystem::create_directory_symlink(dir.path, dir / "link");
    for (const std::string& args : {" --stats " + (dir / "sub/../x.png"), " --stats " + dir.path.string() + "/./x.exr",
                                    " --stats " + (dir / "link/x.exr"), " --visibility " + (dir / "link/x.png")}) {
        INFO(args);
        requireCleanError(runPenumbra(bake + args), "is named for two outputs of this bake");
        for (const char* name : {"x.exr", "x.png"}) CHECK_FALSE(std::filesystem::exists(dir / name));
    }
    RunResult apart = runPenumbra(bake + " --visibility " + (dir / "v.npy") + " --stats " + (dir / "s.json") + " --dump " + (dir / "d"));
    CHECK(apart.exitCode == 0);
    for (const char* name : {"x.exr", "x.png", "v.npy", "s.json", "d/masks.npy"}) CHECK(std::filesystem::exists(dir / name));
    CHECK(slurp(dir / "scene.json") == sceneOf("quad.obj").dump());
}

TEST_CASE("an output naming a device node is written into and stays a device", "[cli][paths]") {
    ScratchDir dir("device-output");
    write(dir / "quad.obj", kQuad);
    nlohmann::json s = sceneOf("quad.obj");
    s["receivers"] = {{"type", "points"}, {"path", "pts.csv"}};
    write(dir / "pts.csv", "0,0,0,0,1,0\n");
    write(dir / "scene.json", s.dump());
    if (::mknod((dir / "null").c_str(), S_IFCHR | 0666, makedev(1, 3)) != 0) {
        WARN("skipped: cannot mknod here (needs root / CAP_MKNOD)");
        return;
    }
    RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q -o " + (dir / "null") + " --stats " + (dir / "null2"));
    INFO(r.err);
    CHECK(r.exitCode == 0);
    CHECK(r.err.empty());
    struct stat st {};
    REQUIRE(::lstat((dir / "null").c_str(), &st) == 0);
    CHECK(S_ISCHR(st.st_mode));
    // A volume writes its one .vdb and nothing named after it, so a device is accepted there too;
    // a camera's preview would be named after it ("null.png"), so its extension is required.
    s["receivers"] = {{"type", "volume"}, {"box", {{-0.5, 0.1, -0.5}, {0.5, 0.3, 0.5}}}, {"voxel_size", 0.1}};
    s["output"] = "out/v.vdb";
    write(dir / "volume.json", s.dump());
    r = runPenumbra("bake " + (dir / "volume.json") + " -q -o " + (dir / "null"));
    INFO(r.err);
    CHECK(r.exitCode == 0);
    REQUIRE(::lstat((dir / "null").c_str(), &st) == 0);
    CHECK(S_ISCHR(st.st_mode));
    requireCleanError(runPenumbra("bake " + (dir / "volume.json") + " -q -o " + (dir / "v.exr")), "volume receivers write .vdb files");
    // Any other name holds the .npy a points bake writes, with a word about it.
    r = runPenumbra("bake " + (dir / "scene.json") + " -q -o " + (dir / "v.exr"));
    CHECK(r.exitCode == 0);
    CHECK_THAT(r.err, Catch::Contains("holds a NumPy .npy array"));
}

TEST_CASE("a failing output of a bake leaves none of its outputs, and none half written", "[cli][paths]") {
    ScratchDir dir("output-set");
    write(dir / "quad.obj", kQuad);
    write(dir / "scene.json", sceneOf("quad.obj").dump());
    fs::create_directories(dir.path / "out");
    write(dir / "out/x.exr", "previous exr");
    if (::mknod((dir / "full").c_str(), S_IFCHR | 0666, makedev(1, 7)) == 0) {
        // The stats go last, into a device that refuses them: the EXR and PNG must not be committed.
        requireCleanError(runPenumbra("bake " + (dir / "scene.json") + " -q --stats " + (dir / "full")), "full: write failed");
        CHECK(slurp(dir / "out/x.exr") == "previous exr");
        CHECK_FALSE(fs::exists(dir / "out/x.png"));
    }
    // An unwritable location is found before any work: the dump directory is a file.
    write(dir / "file", "x");
    RunResult r = runPenumbra("bake " + (dir / "scene.json") + " --dump " + (dir / "file") + "/d");
    requireCleanError(r, "is not a directory");
    CHECK(r.err.find("[scan]") == std::string::npos);
    CHECK(slurp(dir / "out/x.exr") == "previous exr");
    CHECK_FALSE(hasTempFiles(dir.path));
}

TEST_CASE("a failing stderr or a closed pipe never changes a successful bake's exit status", "[cli][paths]") {
    ScratchDir dir("stderr");
    write(dir / "quad.obj", kQuad);
    write(dir / "scene.json", sceneOf("quad.obj").dump());
    const std::string bake = std::string(PENUMBRA_BINARY) + " bake " + (dir / "scene.json");
    CHECK(runShell(bake + " 2>/dev/full") == 0);
    CHECK(runShell(bake + " 2>&-") == 0);
    CHECK(runShell(bake + " >&- 2>&-") == 0);
    // `| head` closes the pipe after the first progress line; the bake goes on and succeeds.
    CHECK(runShell("bash -c 'set -o pipefail; " + bake + " 2>&1 | head -c 1 >/dev/null'") == 0);
    CHECK(fs::exists(dir / "out/x.exr"));
    // A warning into a failing stderr is lost, and nothing else happens.
    write(dir / "prose.obj", "no faces here\n");
    CHECK(runShell(std::string(PENUMBRA_BINARY) + " info " + (dir / "prose.obj") + " 2>/dev/full >/dev/null") == 0);
    // A result that cannot be printed is an error.
    CHECK(runShell(std::string(PENUMBRA_BINARY) + " info " + (dir / "quad.obj") + " >/dev/full 2>/dev/null") == 1);
}

TEST_CASE("two bakes writing one output at once leave a complete file from one of them", "[cli][paths]") {
    ScratchDir dir("concurrent");
    write(dir / "quad.obj", kQuad);
    nlohmann::json a = sceneOf("quad.obj", "shared.exr"), b = a;
    b["receivers"]["width"] = 24;
    write(dir / "a.json", a.dump());
    write(dir / "b.json", b.dump());
    const std::string bin = PENUMBRA_BINARY;
    CHECK(runShell("cd " + dir.path.string() + " && (" + bin + " bake a.json -q & " + bin + " bake b.json -q; wait) 2>/dev/null") == 0);
    const std::string exr = slurp(dir / "shared.exr");
    REQUIRE(exr.size() > 4);
    CHECK(exr.substr(0, 4) == std::string("\x76\x2f\x31\x01", 4));  // an EXR, complete enough to open
    CHECK(dir.entries() == (std::vector<std::string>{"a.json", "b.json", "quad.obj", "shared.exr", "shared.png"}));
}

TEST_CASE("a bake the plan expects to take hours says so first, unless quiet", "[cli][paths]") {
    ScratchDir dir("long-bake");
    nlohmann::json s = sceneOf("quad.obj");
    s["geometry"] = listOf({{"type", "terrain"}, {"resolution", 65536}});
    write(dir / "scene.json", s.dump());
    // Without buckets there is no disk to refuse it; the note comes before the first triangle.
    RunResult r = runPenumbra("bake " + (dir / "scene.json") + " --threads 1 --disable sort", "timeout 5");
    CHECK_THAT(r.err, Catch::Contains("penumbra: note: this bake streams 8589934592 triangles 3 times; expect about"));
    RunResult quiet = runPenumbra("bake " + (dir / "scene.json") + " --threads 1 --disable sort -q", "timeout 3");
    CHECK(quiet.err.find("note:") == std::string::npos);
}

TEST_CASE("generate killed while writing leaves no temporary, SIGKILL included", "[cli][paths]") {
    ScratchDir dir("killed");
    nlohmann::json s = sceneOf("quad.obj", "out.exr");
    // 200M triangles: seconds of writing, killed after half of one. With job control (set -m) a
    // background job does not inherit the ignored SIGINT and SIGQUIT of a non-interactive shell.
    s["geometry"] = listOf({{"type", "grass"}, {"count", 40000000}, {"area", {{-2, -2}, {2, 2}}}});
    write(dir / "scene.json", s.dump());
    write(dir / "old.ptri", "previous");
    for (const char* sig : {"KILL", "HUP", "QUIT", "TERM", "INT"}) {
        INFO(sig);
        const std::string generate = std::string(PENUMBRA_BINARY) + " generate " + (dir / "scene.json") + " -o " + (dir / "old.ptri");
        const int status = runShell("bash -c 'set -m; " + generate + " -q & pid=$!; sleep 0.5; kill -" + sig + " $pid; wait $pid' 2>/dev/null");
        CHECK(status >= 128);  // the shell's "killed by a signal"
        CHECK(dir.entries() == (std::vector<std::string>{"old.ptri", "scene.json"}));
        CHECK(slurp(dir / "old.ptri") == "previous");
    }
}

TEST_CASE("an output folder that does not exist, or through a file, is refused and makes nothing", "[cli][paths]") {
    // penumbra makes the scene's own output folder, never one typed by hand (a typo, most often).
    ScratchDir dir("output-folder");
    write(dir / "quad.obj", kQuad);
    write(dir / "scene.json", sceneOf("quad.obj").dump());
    write(dir / "afile", "a file");
    requireCleanError(runPenumbra("bake " + (dir / "scene.json") + " -q -o " + (dir / "typo/deeper/x.exr")),
                      "typo/deeper does not exist (create it first)");
    CHECK_FALSE(fs::exists(dir.path / "typo"));
    requireCleanError(runPenumbra("bake " + (dir / "scene.json") + " -q -o " + (dir / "afile/x.exr")), "afile is not a folder");
    CHECK(slurp(dir / "afile") == "a file");
    // A path long enough that the message quotes it twice still ends with the reason (a line cut
    // at 1 KiB lost it).
    const std::string deep = dir / (std::string(200, 'a') + "/" + std::string(200, 'b') + "/" + std::string(200, 'c') + "/x.exr");
    requireCleanError(runPenumbra("bake " + (dir / "scene.json") + " -q -o " + deep), "does not exist (create it first)");
}

TEST_CASE("$TMPDIR: empty means /tmp, and one that is no folder is named by its value", "[cli][paths]") {
    ScratchDir dir("tmpdir");
    write(dir / "quad.obj", kQuad);
    write(dir / "scene.json", sceneOf("quad.obj").dump());
    CHECK(runPenumbra("bake " + (dir / "scene.json") + " -q", "TMPDIR=").exitCode == 0);  // as mktemp and Python take it
    requireCleanError(runPenumbra("bake " + (dir / "scene.json") + " -q", "TMPDIR=" + (dir / "nowhere")),
                      "$TMPDIR (" + (dir / "nowhere") + "): cannot use it as the temporary directory");
}

TEST_CASE("the folders of --stats, --visibility and --dump are made, as the README says", "[cli][paths]") {
    // --visibility into a missing folder failed after the bake, while --stats and --dump made theirs.
    ScratchDir dir("side-folders");
    write(dir / "quad.obj", kQuad);
    write(dir / "scene.json", sceneOf("quad.obj").dump());
    const RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q --stats " + (dir / "s/a/st.json") + " --visibility " +
                                    (dir / "v/a/vis.npy") + " --dump " + (dir / "d/a"));
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    CHECK(fs::is_regular_file(dir.path / "s/a/st.json"));
    CHECK(fs::is_regular_file(dir.path / "v/a/vis.npy"));
    CHECK(fs::is_regular_file(dir.path / "d/a/masks.npy"));
}
