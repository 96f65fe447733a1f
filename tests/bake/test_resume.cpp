// Resume after a kill (issue #20): a bake with --checkpoint killed by SIGKILL at any phase, or
// stopped by SIGTERM, and then run again with the same command, writes the bytes of one
// uninterrupted bake, and no kill leaves a temporary file. The kills and signals land at known
// places through test hooks (stream/util/StopRequest.h), never by timing.

#include "ShardScenes.h"

#include "bake/shard/Checkpoint.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

using namespace penumbra::test;
namespace fs = std::filesystem;

namespace {

/// A tiled bake of kShardScene with a dump, its expected bytes and its checkpointing command.
struct ResumeBake {
    ScratchDir dir{"resume"};
    std::string scene, common, expected, command;

    ResumeBake() {
        const TiledScene tiled = tiledShardScene(dir);
        scene = tiled.path;
        common = " --memory-budget " + std::to_string(tiled.budget) + " --threads 2 --dump " + dir / "dump";
        bakeOk(scene + common);
        expected = outputs();
        clean();
        command = "bake " + scene + common + " --checkpoint " + dir / "ckpt" + " --quiet";
    }
    std::string outputs() const { return shardSceneOutputs(dir.path.string(), dir / "dump"); }
    void clean() const { fs::remove_all(dir / "out"), fs::remove_all(dir / "dump"); }
    size_t checkpoints() const { return filesIn(dir / "ckpt").size(); }

    /// The checkpointing command run with @p env, which must end it by SIGKILL, leaving no output
    /// and no temporary file.
    void killed(const std::string& env) const {
        RunResult r = runPenumbra(command, env);
        INFO(env << "\n" << r.err);
        REQUIRE(r.exitCode == 128 + 9);
        CHECK_FALSE(fs::exists(dir / "out/scene.exr"));
        CHECK_FALSE(fs::exists(dir / "dump/masks.npy"));
        CHECK_FALSE(hasTempFiles(dir.path));
    }

    /// The command run in the background with @p env, paused at a test point (PENUMBRA_TEST_PAUSE_AT);
    /// once it is there it gets @p first, and when @p second is given, once it holds after the
    /// first, @p second too. @return the exit code the shell saw (128 + N when killed by signal N).
    int signalled(const std::string& env, const std::string& first, const std::string& second = "") const {
        const std::string ready = dir / "ready", held = dir / "held";
        fs::remove(ready), fs::remove(held);
        // The waits are bounded (60 s) only so that a broken hook fails the test instead of hanging it.
        std::string script = "PENUMBRA_TEST_PAUSE_FILE=" + ready + " " + env +
                             (second.empty() ? "" : " PENUMBRA_TEST_HOLD_AFTER_STOP=" + held) + " " + PENUMBRA_BINARY +
                             " " + command + " 2>" + dir / "err" + " & pid=$!; " + waitFor(ready) + " kill -" + first +
                             " $pid; ";
        if (!second.empty()) script += waitFor(held) + " kill -" + second + " $pid; ";
        script += "wait $pid";
        // Job control (set -m): a background job of a shell without it ignores SIGINT.
        return runShell("bash -c 'set -m; exec 2>/dev/null; " + script + "'");
    }
    static std::string waitFor(const std::string& file) {
        return "for i in $(seq 1200); do [ -e " + file + " ] && break; sleep 0.05; done;";
    }
    std::string err() const { return slurp(dir / "err"); }

    /// The same command, uninterrupted: the outputs must be the expected bytes and the checkpoints gone.
    void resumes() const {
        RunResult r = runPenumbra(command);
        INFO(r.err);
        REQUIRE(r.exitCode == 0);
        CHECK(outputs() == expected);
        CHECK(filesIn(dir / "ckpt").empty());  // the bake is complete: its checkpoints are gone
        CHECK_FALSE(fs::exists(dir / "ckpt"));  // and the folder they were in, left empty
        CHECK_FALSE(hasTempFiles(dir.path));
    }
};

}  // namespace

TEST_CASE("a bake killed with SIGKILL at every phase resumes to the same bytes", "[shards][resume]") {
    ResumeBake b;
    // The scan and the bucket pass keep nothing (the bucket files were anonymous).
    b.killed("PENUMBRA_TEST_KILL_AT=scan");
    b.killed("PENUMBRA_TEST_KILL_AT=bucket");
    CHECK(b.checkpoints() == 0);
    b.killed("PENUMBRA_TEST_KILL_AFTER_TILES=1");  // between tiles: the first is on disk
    CHECK(b.checkpoints() == 1);
    b.killed("PENUMBRA_TEST_KILL_AT=cast");  // in the middle of the second tile, the first restored
    CHECK(b.checkpoints() == 1);
    b.killed("PENUMBRA_TEST_KILL_AFTER_TILES=2");  // between tiles again, two more on disk
    CHECK(b.checkpoints() == 3);
    b.killed("PENUMBRA_TEST_KILL_AT=write");  // every tile on disk, the image finished, none in place
    const size_t tiles = b.checkpoints();
    CHECK(tiles >= 3);
    b.killed("PENUMBRA_TEST_KILL_AT=write");  // all tiles restored: a kill while writing again
    CHECK(b.checkpoints() == tiles);
    b.resumes();
}

TEST_CASE("a resumed bake shades restored and cast tiles as phases of their own, once per receiver", "[shards][resume][progress]") {
    ResumeBake b;
    b.killed("PENUMBRA_TEST_KILL_AFTER_TILES=1");  // the first tile on disk
    REQUIRE(b.checkpoints() == 1);
    std::string loud = b.command;
    loud.erase(loud.rfind(" --quiet"));
    RunResult r = runPenumbra(loud + " --stats " + b.dir / "s.json");
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    CHECK(b.outputs() == b.expected);
    // stderr is not a terminal: each phase's closing line, one [shade] per memory tile (the
    // restored one first), and the cast's single closing line before the last tile's [shade].
    uint64_t shaded = 0;
    size_t shadeLines = 0;
    std::istringstream lines(r.err);
    for (std::string line; std::getline(lines, line);) {
        if (line.rfind("[shade] 100.0% (", 0) != 0) continue;
        ++shadeLines;
        shaded += std::stoull(line.substr(16));
    }
    const nlohmann::json stats = nlohmann::json::parse(slurp(b.dir / "s.json"));
    CHECK(shaded == stats["receivers"].get<uint64_t>());
    CHECK(shadeLines >= 3);
    CHECK(r.err.find("[shade] ") < r.err.find("[cast] 100.0%"));  // the restored tile, before the cast ends
    CHECK(r.err.rfind("[shade] ") > r.err.find("[cast] 100.0%"));
}

TEST_CASE("SIGTERM stops a checkpointing bake with exit 143, and a second signal ends it at once", "[shards][resume][sigterm]") {
    ResumeBake b;
    b.killed("PENUMBRA_TEST_KILL_AFTER_TILES=1");
    REQUIRE(b.checkpoints() == 1);

    // SIGTERM in the middle of the second tile: the first stays on disk, the second's progress is
    // written, the process says so and exits 143 without an output or a temporary file.
    CHECK(b.signalled("PENUMBRA_TEST_PAUSE_AT=cast", "TERM") == 143);
    CHECK_THAT(b.err(), Catch::StartsWith("penumbra: stopped by SIGTERM during the cast; 1 memory tile(s) and the "
                                          "progress of the tile in hand checkpointed in"));
    CHECK(lineCount(b.err()) == 1);
    CHECK(b.checkpoints() == 2);
    CHECK_FALSE(fs::exists(b.dir / "out/scene.exr"));
    CHECK_FALSE(hasTempFiles(b.dir.path));

    // During the scan and the bucket pass: nothing to save, the earlier checkpoints are kept.
    CHECK(b.signalled("PENUMBRA_TEST_PAUSE_AT=scan", "TERM") == 143);
    CHECK_THAT(b.err(), Catch::Contains("during the scan; the checkpoints in"));
    CHECK(b.signalled("PENUMBRA_TEST_PAUSE_AT=bucket", "TERM") == 143);
    CHECK_THAT(b.err(), Catch::Contains("during the bucket pass"));
    CHECK(b.checkpoints() == 2);

    // A second SIGTERM, or a SIGINT, while the bake stops: the process ends at once, by the signal.
    // (Held in the scan: this scene's tiles replay a single chunk, so a resumed tile's progress
    // is at the end of its replay and casts nothing where it could pause.)
    CHECK(b.signalled("PENUMBRA_TEST_PAUSE_AT=scan", "TERM", "TERM") == 143);
    CHECK(b.signalled("PENUMBRA_TEST_PAUSE_AT=scan", "TERM", "INT") == 130);
    CHECK_FALSE(hasTempFiles(b.dir.path));
    CHECK(b.checkpoints() == 2);
    b.resumes();

    // Without --checkpoint there is nothing to save: SIGTERM ends the bake at once.
    b.clean();
    b.command = b.command.substr(0, b.command.find(" --checkpoint")) + " --quiet";
    CHECK(b.signalled("PENUMBRA_TEST_PAUSE_AT=cast", "TERM") == 143);
    CHECK(b.err().empty());
    CHECK_FALSE(fs::exists(b.dir / "out/scene.exr"));
    CHECK_FALSE(hasTempFiles(b.dir.path));
}

TEST_CASE("a tile killed or stopped in the middle resumes from its progress checkpoint to the same bytes",
          "[shards][resume]") {
    ScratchDir dir("resume-progress");
    std::string scene = kShardScene;  // 24 cells a side: over 12,000 blockers, several chunks of 4,096
    scene.replace(scene.find("\"cells\": 6"), 10, "\"cells\": 24");
    writeText(dir / "scene.json", scene);
    const std::string common = dir / "scene.json" + " --threads 2 --dump " + dir / "dump";
    bakeOk(common + " --stats " + dir / "whole.json");
    const uint64_t blockers = nlohmann::json::parse(slurp(dir / "whole.json"))["stream"]["triangles"].get<uint64_t>();
    REQUIRE(blockers > 3 * 4096);
    const std::string expected = shardSceneOutputs(dir.path.string(), dir / "dump");
    fs::remove_all(dir / "out"), fs::remove_all(dir / "dump");
    // --checkpoint-every 0: the tile's progress is saved after every chunk of the replay.
    const std::string command = "bake " + common + " --checkpoint " + dir / "ckpt" + " --checkpoint-every 0 --quiet";
    const std::string progressName = penumbra::checkpointNamePrefix(dir / "scene.json", {}) + "tile-0-of-1.progress.pnpart";
    const std::string progress = dir / ("ckpt/" + progressName);
    auto replayed = [&] {  // the replay position in the progress file's header (docs/distributed.md)
        std::ifstream in(progress, std::ios::binary);
        in.seekg(56);  // after the part end of format 3
        uint64_t position = 0;
        in.read(reinterpret_cast<char*>(&position), sizeof position);
        return position;
    };

    // Killed after the first chunk, then (resumed there) after the next one.
    uint64_t last = 0;
    for (int kill = 0; kill < 2; ++kill) {
        RunResult r = runPenumbra(command, "PENUMBRA_TEST_KILL_AT=cast");
        INFO(r.err);
        REQUIRE(r.exitCode == 137);
        REQUIRE(filesIn(dir / "ckpt") == std::vector<std::string>{progressName});
        CHECK(replayed() > last);
        last = replayed();
        CHECK_FALSE(hasTempFiles(dir.path));
    }
    // SIGTERM: resumed, one chunk further, the progress saved again, exit 143.
    const std::string ready = dir / "ready";
    const int stopped = runShell("bash -c 'set -m; exec 2>/dev/null; PENUMBRA_TEST_PAUSE_AT=cast PENUMBRA_TEST_PAUSE_FILE=" +
                                 ready + " " + PENUMBRA_BINARY + " " + command + " & pid=$!; " +
                                 "for i in $(seq 1200); do [ -e " + ready + " ] && break; sleep 0.05; done; kill -TERM $pid; wait $pid'");
    CHECK(stopped == 143);
    CHECK(replayed() > last);
    last = replayed();
    CHECK(last < blockers);
    CHECK_FALSE(fs::exists(dir / "out/scene.exr"));

    // The rest: the replay up to the saved position is skipped, not cast, and the bytes are the same.
    RunResult r = runPenumbra(command + " --stats " + dir / "resumed.json");
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    const nlohmann::json shard = nlohmann::json::parse(slurp(dir / "resumed.json"))["shard"];
    CHECK(shard["tiles_resumed_in_progress"] == 1);
    CHECK(shard["replay_skipped_triangles"] == last);
    CHECK(shardSceneOutputs(dir.path.string(), dir / "dump") == expected);
    CHECK(filesIn(dir / "ckpt").empty());
    CHECK_FALSE(hasTempFiles(dir.path));
}

TEST_CASE("a tile's progress is refused when the replay differs from the blockers it holds", "[shards][resume]") {
    ScratchDir dir("resume-replay");
    auto quadAt = [](double y) { return fmt::format("v -1 {0} -1\nv 1 {0} -1\nv 1 {0} 1\nv -1 {0} 1\nf 1 2 3 4\n", y); };
    writeText(dir / "mesh.obj", quadAt(1.0));
    writeText(dir / "points.csv", "x,y,z,nx,ny,nz\n0,0,0,0,1,0\n0.5,0,0.2,0,1,0\n1.5,0,0,0,1,0\n");
    writeText(dir / "scene.json", R"({"geometry": [{"type": "obj", "path": "mesh.obj"}],
      "lights": [{"type": "rect", "center": [0, 3, 0], "u": [1, 0, 0], "v": [0, 0, 1], "samples": 16}],
      "receivers": {"type": "points", "path": "points.csv"}, "output": "out/p.npy"})");
    const std::string bake = "bake " + dir / "scene.json" + " --checkpoint-every 0";
    REQUIRE(runPenumbra(bake + " --quiet --checkpoint " + dir / "ckpt", "PENUMBRA_TEST_KILL_AT=cast").exitCode == 137);
    REQUIRE(fs::exists(dir / ("ckpt/" + penumbra::checkpointNamePrefix(dir / "scene.json", {}) + "tile-0-of-1.progress.pnpart")));

    // The same scene file, receivers and light samples, but other blockers: the changed file makes
    // another scene (its size and time are in the scene hash), and the saved progress is of
    // another replay besides; it is never used.
    writeText(dir / "mesh.obj", quadAt(1.5));
    requireCleanError(runPenumbra(bake + " --quiet --resume " + dir / "ckpt"), "a checkpoint of another scene file");
    RunResult noted = runPenumbra(bake + " --checkpoint " + dir / "ckpt");
    INFO(noted.err);
    REQUIRE(noted.exitCode == 0);
    CHECK_THAT(noted.err, Catch::Contains("ignoring the checkpoint: a checkpoint of another scene file"));
    const std::string resumed = slurp(dir / "out/p.npy");
    fs::remove_all(dir / "out");
    bakeOk(dir / "scene.json");
    CHECK(slurp(dir / "out/p.npy") == resumed);
    CHECK(filesIn(dir / "ckpt").empty());
    CHECK_FALSE(hasTempFiles(dir.path));
}

TEST_CASE("a damaged checkpoint or one of another scene is refused under --resume, ignored under --checkpoint",
          "[shards][resume]") {
    ResumeBake b;
    const std::string scene = b.scene, common = b.common, command = b.command;
    ScratchDir& dir = b.dir;
    b.killed("PENUMBRA_TEST_KILL_AFTER_TILES=1");
    const std::vector<std::string> files = filesIn(dir / "ckpt");
    REQUIRE(files.size() == 1);
    const std::string file = dir / ("ckpt/" + files[0]);
    fs::resize_file(file, fs::file_size(file) - 3);
    requireCleanError(runPenumbra("bake " + scene + common + " --quiet --resume " + dir / "ckpt"), "truncated");

    // A checkpoint of another scene is never used: the scene file edited since (another scene
    // file's bakes name their checkpoints apart, below).
    const std::string original = slurp(scene);
    const auto modified = fs::last_write_time(scene);  // the EXR's capDate: put back with the text
    std::string other = original;
    other.replace(other.find("\"radius\": 0.5"), 13, "\"radius\": 0.6");
    b.killed("PENUMBRA_TEST_KILL_AFTER_TILES=1");  // a sound one again
    writeText(scene, other);
    requireCleanError(runPenumbra("bake " + scene + common + " --quiet --resume " + dir / "ckpt"), "another scene");
    writeText(scene, original);
    fs::last_write_time(scene, modified);
    // A bake of another scene file in the same folder keeps its own checkpoints, and removes
    // only its own: it replaced this one's, and removed them when it was done.
    writeText(dir / "other.json", other);
    RunResult otherBake = runPenumbra("bake " + dir / "other.json" + common + " -o " + dir / "other.exr" + " --quiet --checkpoint " + dir / "ckpt");
    INFO(otherBake.err);
    REQUIRE(otherBake.exitCode == 0);
    CHECK(filesIn(dir / "ckpt") == std::vector<std::string>{files[0]});

    fs::resize_file(file, fs::file_size(file) - 3);
    RunResult noted = runPenumbra("bake " + scene + common + " --checkpoint " + dir / "ckpt");
    REQUIRE(noted.exitCode == 0);
    CHECK_THAT(noted.err, Catch::Contains("ignoring the checkpoint"));
    CHECK(b.outputs() == b.expected);
    CHECK_FALSE(hasTempFiles(dir.path));

    // --resume of a folder that is not there (a typo, most often) bakes from the start, but says so.
    RunResult typo = runPenumbra("bake " + scene + common + " --quiet --resume " + dir / "ckpt-typo");
    REQUIRE(typo.exitCode == 0);
    CHECK_THAT(typo.err, Catch::Contains("--resume: " + dir / "ckpt-typo" + " does not exist, so there is nothing to resume"));
    CHECK(b.outputs() == b.expected);
}

TEST_CASE("checkpoints of another tiling are refused under --resume, noted and removed under --checkpoint",
          "[shards][resume]") {
    // A bake that looked only for its own tile count's names started over without a word, and
    // left the other tiling's files in the folder for good.
    ResumeBake b;
    ScratchDir& dir = b.dir;
    b.killed("PENUMBRA_TEST_KILL_AFTER_TILES=1");
    REQUIRE(filesIn(dir / "ckpt").size() == 1);
    const std::string untiled = " --threads 2 --dump " + dir / "dump";  // no budget: one tile, not three or more
    requireCleanError(runPenumbra("bake " + b.scene + untiled + " --quiet --resume " + dir / "ckpt"), "another tiling");
    RunResult noted = runPenumbra("bake " + b.scene + untiled + " --checkpoint " + dir / "ckpt");
    INFO(noted.err);
    REQUIRE(noted.exitCode == 0);
    CHECK_THAT(noted.err, Catch::Contains("ignoring 1 checkpoint file(s) of this bake in another tiling (this bake has 1 tile(s)"));
    CHECK(b.outputs() == b.expected);  // tiles never change the bytes
    CHECK_FALSE(fs::exists(dir / "ckpt"));
    CHECK_FALSE(hasTempFiles(dir.path));
}

TEST_CASE("a checkpoint renamed to another tile is refused before any tile is cast under --resume, ignored under --checkpoint",
          "[shards][resume]") {
    // It was refused only when tile 0 was cast, with a message about another tiling.
    ResumeBake b;
    ScratchDir& dir = b.dir;
    b.killed("PENUMBRA_TEST_KILL_AFTER_TILES=1");
    const std::vector<std::string> files = filesIn(dir / "ckpt");
    REQUIRE(files.size() == 1);
    const size_t at = files[0].find("tile-0-of-");
    REQUIRE(at != std::string::npos);
    std::string renamed = files[0];
    renamed.replace(at, 6, "tile-1");
    fs::rename(dir / ("ckpt/" + files[0]), dir / ("ckpt/" + renamed));
    RunResult refused = runPenumbra("bake " + b.scene + b.common + " --quiet --resume " + dir / "ckpt");
    requireCleanError(refused, "holds tile 0 of");
    CHECK_THAT(refused.err, Catch::Contains(renamed) && Catch::Contains("not tile 1 of") && Catch::Contains("(renamed?)"));
    RunResult shown = runPenumbra("bake " + b.scene + b.common + " --resume " + dir / "ckpt");
    CHECK(shown.exitCode == 1);
    CHECK_THAT(shown.err, Catch::Contains("[bucket]") && !Catch::Contains("[cast"));  // refused before any tile was cast
    CHECK_FALSE(fs::exists(dir / "out/scene.exr"));

    RunResult noted = runPenumbra("bake " + b.scene + b.common + " --checkpoint " + dir / "ckpt");
    INFO(noted.err);
    REQUIRE(noted.exitCode == 0);
    CHECK_THAT(noted.err, Catch::Contains("ignoring the checkpoint: holds tile 0 of"));
    CHECK(b.outputs() == b.expected);
    CHECK_FALSE(fs::exists(dir / "ckpt"));
    CHECK_FALSE(hasTempFiles(dir.path));
}

TEST_CASE("methods without memory tiles refuse --checkpoint and --resume before any work", "[shards][resume]") {
    // They took the option, saved nothing, and lost the whole cast to a SIGTERM without a word.
    ScratchDir dir("resume-methods");
    const TiledScene tiled = tiledShardScene(dir);
    for (const std::string method : {"reference", "embree", "ssv", "penumbra-map"}) {
        for (const std::string option : {"--checkpoint", "--resume"}) {
            INFO(method << " " << option);
            RunResult r = runPenumbra("bake " + tiled.path + " --quiet --method " + method + " " + option + " " + dir / "ckpt");
            requireCleanError(r, option + ": --method " + method + " has no memory tiles to save; only hpc checkpoints");
            // Sharding is offered only to methods that can shard (penumbra-map has no masks to merge).
            CHECK((r.err.find("or shard the bake") != std::string::npos) == (method != "penumbra-map"));
            CHECK_FALSE(fs::exists(dir / "ckpt"));
            CHECK_FALSE(fs::exists(dir / "out"));
        }
    }
}

TEST_CASE("checkpoints and shard files are synced before they are named, and their directory after", "[shards][resume][fsync]") {
    ScratchDir dir("resume-fsync");
    writeText(dir / "scene.json", kShardScene);
    if (runShell("strace -o /dev/null true >/dev/null 2>&1") != 0) {
        WARN("strace is missing or cannot trace here: the order of fsync and link is not checked");
        return;
    }
    const std::string trace = dir / "trace";
    const std::string traced = "strace -f -qq -e trace=fsync,linkat,renameat2,rename -o " + trace + " ";
    for (const std::string& args : {" --checkpoint " + dir / "ckpt", " --shard 0/2 --shard-dir " + dir / "shards"}) {
        RunResult r = runPenumbra("bake " + dir / "scene.json" + args + " --quiet", traced);
        INFO(r.err);
        REQUIRE(r.exitCode == 0);
        // Each partial file: fsync of its descriptor, its link into place, fsync of the directory.
        std::ifstream in(trace);
        std::vector<std::string> calls;
        for (std::string line; std::getline(in, line);) calls.push_back(line);
        const std::string name = args.find("--shard ") != std::string::npos ? "shard-0-of-2.pnpart" : "tile-0-of-1.pnpart";
        size_t link = 0;
        while (link < calls.size() && calls[link].find(name) == std::string::npos) ++link;
        INFO(slurp(trace));
        REQUIRE(link < calls.size());
        REQUIRE(link >= 1);
        CHECK(calls[link - 1].find("fsync(") != std::string::npos);
        REQUIRE(link + 1 < calls.size());
        CHECK(calls[link + 1].find("fsync(") != std::string::npos);
    }
}

TEST_CASE("shards given one checkpoint folder keep their own checkpoints and resume from them", "[shards][resume]") {
    // The names were the tile's alone: shard 1's tile 0 replaced shard 0's, and shard 0's
    // --resume then refused it as a checkpoint of other settings.
    ResumeBake b;
    const std::string shards = b.dir / "shards";
    auto shardCommand = [&](int i) {
        return "bake " + b.scene + b.common.substr(0, b.common.find(" --dump")) + fmt::format(" --shard {}/2 --shard-by receivers", i) +
               " --shard-dir " + shards + " --resume " + b.dir / "ckpt" + " --quiet";
    };
    for (int i = 0; i < 2; ++i) {
        RunResult r = runPenumbra(shardCommand(i), "PENUMBRA_TEST_KILL_AFTER_TILES=1");
        INFO(r.err);
        REQUIRE(r.exitCode == 128 + 9);
    }
    std::vector<std::string> saved = filesIn(b.dir / "ckpt");
    std::sort(saved.begin(), saved.end());
    REQUIRE(saved.size() == 2);
    const std::string stem = penumbra::checkpointNamePrefix(b.scene, {});
    CHECK(saved[0].rfind(stem + "shard-0-of-2.tile-0-of-", 0) == 0);
    CHECK(saved[1].rfind(stem + "shard-1-of-2.tile-0-of-", 0) == 0);
    for (int i = 0; i < 2; ++i) {
        const std::string stats = b.dir / fmt::format("s{}.json", i);
        RunResult r = runPenumbra(shardCommand(i) + " --stats " + stats);
        INFO(r.err);
        REQUIRE(r.exitCode == 0);
        CHECK(nlohmann::json::parse(slurp(stats))["shard"]["tiles_restored"] == 1);
    }
    CHECK_FALSE(fs::exists(b.dir / "ckpt"));  // both complete: their checkpoints and the folder are gone
    RunResult merge = runPenumbra("merge " + b.scene + " --shard-dir " + shards + " --quiet --dump " + b.dir / "dump");
    INFO(merge.err);
    REQUIRE(merge.exitCode == 0);
    CHECK(b.outputs() == b.expected);
}

TEST_CASE("a bake resumed after its scene file was moved uses the checkpoints saved under the old path",
          "[shards][resume]") {
    // Checkpoints are named after the scene file's path, so that bakes of different scene files
    // may share a folder; a --resume after a move found none of its own and cast from the start
    // without a word. Their headers say whose they are, so they are renamed and used.
    ResumeBake b;
    ScratchDir& dir = b.dir;
    b.killed("PENUMBRA_TEST_KILL_AFTER_TILES=1");
    REQUIRE(b.checkpoints() == 1);
    const std::string moved = dir / "moved.json";
    fs::rename(b.scene, moved);  // keeps its modification time: the same scene
    RunResult r = runPenumbra("bake " + moved + b.common + " --resume " + dir / "ckpt" + " --stats " + dir / "s.json");
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.err, Catch::Contains("using 1 checkpoint file(s) of this bake saved under another path of its scene file"));
    CHECK(slurp(dir / "s.json").find("\"tiles_restored\": 1") != std::string::npos);
    CHECK(b.outputs() == b.expected);
    CHECK_FALSE(fs::exists(dir / "ckpt"));
    CHECK_FALSE(hasTempFiles(dir.path));
}
