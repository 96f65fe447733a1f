// By-blockers shards make only their share of the stream (#18): a generator skips the blocks of
// the other shards instead of generating them, and the shares still merge to the unsharded bytes.

#include "CliRunner.h"

#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "procedural/Generators.h"
#include "stream/SourceRegistry.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <fmt/format.h>

#include <atomic>
#include <filesystem>
#include <fstream>

using namespace penumbra;
using namespace penumbra::test;
namespace fs = std::filesystem;

namespace {

/// Counts the triangles another source hands out; skips are passed on, uncounted.
class CountingSource final : public TriangleSource {
public:
    CountingSource(TriangleSourcePtr inner, std::atomic<uint64_t>& made) : inner_(std::move(inner)), made_(made) {}
    size_t read(std::span<Triangle> out) override {
        const size_t n = inner_->read(out);
        made_ += n;
        return n;
    }
    void rewind() override { inner_->rewind(); }
    uint64_t skip(uint64_t count) override { return inner_->skip(count); }
    std::string name() const override { return inner_->name(); }
    std::optional<uint64_t> sizeHint() const override { return inner_->sizeHint(); }

private:
    TriangleSourcePtr inner_;
    std::atomic<uint64_t>& made_;
};

std::atomic<uint64_t> grassMade{0};

/// Grass on a floor under a light: 20,000 blades of 5 triangles, seen by a small camera.
nlohmann::json grassScene(const std::string& grassType) {
    nlohmann::json scene = nlohmann::json::parse(R"({
      "geometry": [{"type": "grid", "cells": 1, "levels": 0, "size": 1, "floor_size": 6},
                   {"type": "grass", "count": 20000, "area": [[-2, -2], [2, 2]], "height": [0.2, 0.5], "seed": 3}],
      "lights": [{"type": "rect", "center": [0.5, 3, 0.2], "u": [0.6, 0, 0], "v": [0, 0, 0.6], "samples": 64, "sample_sets": 4}],
      "receivers": {"type": "camera", "eye": [0, 2.5, 3], "target": [0, 0, 0], "width": 48, "height": 36},
      "output": "out/grass.exr"})");
    scene["geometry"][1]["type"] = grassType;
    return scene;
}

void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

void bakeOk(const std::string& args) {
    RunResult r = runPenumbra(args + " --quiet");
    INFO("penumbra " << args << "\n" << r.err);
    REQUIRE(r.exitCode == 0);
}

}  // namespace

TEST_CASE("a by-blockers shard generates only its share of a generator's stream", "[shards]") {
    registerProceduralGenerators();
    registerSourceType("counted-grass", [](const SourceRequest& r) {
        nlohmann::json params = r.params;
        params.erase("type");
        return TriangleSourcePtr(std::make_unique<CountingSource>(openSource("grass", SourceRequest{params, r.file, r.path, r.baseDir}), grassMade));
    });
    ScratchDir dir("shard-share");
    write(dir / "scene.json", grassScene("counted-grass").dump());  // a shard file names its scene by hash
    const uint64_t blades = 20000 * 5;
    auto bakeShard = [&](uint32_t index, uint32_t count) {
        BakeSettings settings;
        settings.quiet = true;
        settings.threads = 2;
        settings.shard.index = index, settings.shard.count = count, settings.shard.cut = ShardCut::Blockers;
        settings.shard.dir = dir / "shards";
        grassMade = 0;
        const nlohmann::json stats = runBake(parseScene(grassScene("counted-grass"), dir / "scene.json"), settings);
        return std::pair(grassMade.load(), stats["shard"]["blockers_cast"].get<uint64_t>());
    };
    uint64_t cast = 0;
    for (uint32_t i = 0; i < 4; ++i) {
        const auto [made, blockers] = bakeShard(i, 4);
        INFO("shard " << i);
        // The scan sees every blade (the camera's z-buffer needs them all); the bucket pass makes
        // only the shard's quarter, give or take a block.
        CHECK(made > blades);
        CHECK(made - blades < blades / 4 + 2048);
        CHECK(made - blades > blades / 4 - 2048);
        cast += blockers;
    }
    // An unsharded bake makes the stream twice; the shares hold each of its triangles once.
    BakeSettings whole;
    whole.quiet = true;
    grassMade = 0;
    const nlohmann::json stats = runBake(parseScene(grassScene("counted-grass"), dir / "scene.json"), whole);
    CHECK(grassMade.load() == 2 * blades);
    CHECK(cast == stats["stream"]["triangles"].get<uint64_t>());
}

TEST_CASE("by-receivers shards' blocked relations add up to the whole bake's", "[shards]") {
    registerProceduralGenerators();
    // Each shard counted the other shards' receivers, which it does not cast, as fully blocked.
    ScratchDir dir("shard-blocked-relations");
    write(dir / "scene.json", grassScene("grass").dump());
    auto bake = [&](uint32_t index, uint32_t count) {
        BakeSettings settings;
        settings.quiet = true;
        if (count) {
            settings.shard.index = index, settings.shard.count = count, settings.shard.cut = ShardCut::Receivers;
            settings.shard.dir = dir / "shards";
        }
        return runBake(parseScene(grassScene("grass"), dir / "scene.json"), settings)["blocked_relations"].get<uint64_t>();
    };
    const uint64_t whole = bake(0, 0);
    REQUIRE(whole > 0);
    uint64_t sum = 0;
    for (uint32_t i = 0; i < 3; ++i) sum += bake(i, 3);
    CHECK(sum == whole);
}

TEST_CASE("generated shares merge to the unsharded bytes", "[shards]") {
    ScratchDir dir("shard-share-merge");
    write(dir / "grass.json", grassScene("grass").dump());
    bakeOk("bake " + dir / "grass.json");
    const std::string expected = slurp(dir / "out/grass.exr") + slurp(dir / "out/grass.png");
    REQUIRE(expected.size() > 1000);
    for (int n : {3, 5}) {
        const std::string shards = dir / fmt::format("s{}", n);
        for (int i = 0; i < n; ++i)
            bakeOk("bake " + dir / "grass.json" + fmt::format(" --shard {}/{} --shard-by blockers --shard-dir {}", i, n, shards));
        fs::remove_all(dir / "out");
        const RunResult merged = runPenumbra("merge " + dir / "grass.json" + " --shard-dir " + shards);
        INFO(merged.err);
        REQUIRE(merged.exitCode == 0);
        CHECK(slurp(dir / "out/grass.exr") + slurp(dir / "out/grass.png") == expected);
        // The merged masks are shaded as a phase of its own, counting every receiver.
        CHECK_THAT(merged.err, Catch::Contains("[shade] 100.0% (") && Catch::Contains(") done in "));
    }
}

TEST_CASE("a tree of combines merges to the unsharded bytes, for either cut", "[shards]") {
    ScratchDir dir("shard-tree");
    write(dir / "grass.json", grassScene("grass").dump());
    const std::string scene = dir / "grass.json";
    bakeOk("bake " + scene);
    const std::string expected = slurp(dir / "out/grass.exr") + slurp(dir / "out/grass.png");
    for (const char* cut : {"blockers", "receivers"}) {
        const std::string shards = dir / fmt::format("{}-shards", cut), level = dir / fmt::format("{}-level1", cut);
        for (int i = 0; i < 5; ++i) bakeOk("bake " + scene + fmt::format(" --shard {}/5 --shard-by {} --shard-dir {}", i, cut, shards));
        // Two inner nodes, of shards 0-1 and 2-4, then the merge of their two files.
        bakeOk("combine " + shards + " --range 0-1 --shard-dir " + level);
        bakeOk("combine " + shards + " --range 2-4 --shard-dir " + level);
        CHECK(fs::exists(level + "/shards-0-1-of-5.pnpart"));
        CHECK(fs::exists(level + "/shards-2-4-of-5.pnpart"));
        fs::remove_all(dir / "out");
        bakeOk("merge " + scene + " --shard-dir " + level);
        INFO(cut);
        CHECK(slurp(dir / "out/grass.exr") + slurp(dir / "out/grass.png") == expected);
        // One more level, combining files given by name: one file of all five shards.
        const std::string top = dir / fmt::format("{}-top", cut);
        RunResult r = runPenumbra("combine " + level + "/shards-2-4-of-5.pnpart " + level + "/shards-0-1-of-5.pnpart --shard-dir " + top);
        REQUIRE(r.exitCode == 0);
        CHECK(r.out.find("shards-0-4-of-5.pnpart") != std::string::npos);
        fs::remove_all(dir / "out");
        bakeOk("merge " + scene + " --shard-dir " + top);
        CHECK(slurp(dir / "out/grass.exr") + slurp(dir / "out/grass.png") == expected);
    }
}

TEST_CASE("combine and merge refuse overlaps, gaps and files of other bakes", "[shards][cli]") {
    ScratchDir dir("shard-tree-bad");
    write(dir / "grass.json", grassScene("grass").dump());
    const std::string scene = dir / "grass.json";
    for (int i = 0; i < 4; ++i) bakeOk("bake " + scene + fmt::format(" --shard {}/4 --shard-by blockers --shard-dir {}", i, dir / "s"));
    bakeOk("combine " + dir / "s" + " --range 0-1 --shard-dir " + dir / "l");
    // The combined file beside a shard it holds: shard 1 twice.
    fs::copy_file(dir / "s/shard-1-of-4.pnpart", dir / "l/shard-1-of-4.pnpart");
    requireCleanError(runPenumbra("merge " + scene + " --shard-dir " + dir / "l" + " --quiet"), "overlap");
    fs::remove(dir / "l/shard-1-of-4.pnpart");
    requireCleanError(runPenumbra("merge " + scene + " --shard-dir " + dir / "l" + " --quiet"), "missing 2 of 4 shards (2, 3)");
    // A range with a hole, a file across the range's edge, a range past the shards.
    fs::create_directories(dir / "holey");
    for (int i : {0, 2}) fs::copy_file(dir / fmt::format("s/shard-{}-of-4.pnpart", i), dir / fmt::format("holey/shard-{}-of-4.pnpart", i));
    requireCleanError(runPenumbra("combine " + dir / "holey" + " --range 0-2 --shard-dir " + dir / "x"), "missing 1 of 3 shards (1)");
    requireCleanError(runPenumbra("combine " + dir / "l/shards-0-1-of-4.pnpart " + dir / "s/shard-2-of-4.pnpart --range 1-2 --shard-dir " + dir / "x"),
                      "across the edge of the range 1-2");
    requireCleanError(runPenumbra("combine " + dir / "s" + " --range 3-1 --shard-dir " + dir / "x"), "--range");
    // Past the last shard: named as such, not as shards "missing" from a bake of more.
    requireCleanError(runPenumbra("combine " + dir / "s" + " --range 2-5 --shard-dir " + dir / "x"),
                      "--range: 2-5 goes past the last shard of this bake (4 shards: 0-3)");
    // Shards of another cut.
    bakeOk("bake " + scene + " --shard 3/4 --shard-by receivers --shard-dir " + dir / "r");
    requireCleanError(runPenumbra("combine " + dir / "s/shard-2-of-4.pnpart " + dir / "r/shard-3-of-4.pnpart --shard-dir " + dir / "x"), "cut by");
    CHECK_FALSE(fs::exists(dir / "x"));
    // A write that fails (a full disk) leaves neither a file nor the folder it made for it.
    const RunResult full = runPenumbra("combine " + dir / "s" + " --range 0-1 --shard-dir " + dir / "y/z", "prlimit --fsize=100");
    CHECK(full.exitCode == 1);
    CHECK_THAT(full.err, Catch::StartsWith("penumbra: error: "));
    CHECK_FALSE(fs::exists(dir / "y"));
    CHECK_FALSE(hasTempFiles(dir.path));
}

TEST_CASE("penumbra slurm puts a tree of combine jobs between many shards and the merge", "[shards][cli]") {
    ScratchDir dir("slurm-tree");
    write(dir / "grass.json", grassScene("grass").dump());
    RunResult r = runPenumbra("slurm " + dir / "grass.json" + " --shards 10 --fan-in 3 --dir " + dir / "job" + " --dry-run");
    REQUIRE(r.exitCode == 0);
    // 10 shards, at most 3 files a job: 4 combines of 3 shards, 2 of 9, then the merge reads 2.
    const std::string& s = r.out;
    CHECK(s.find("combine-1.sbatch") != std::string::npos);
    CHECK(s.find("#SBATCH --array=0-3\n") != std::string::npos);
    CHECK(s.find("first=$((SLURM_ARRAY_TASK_ID * 3)); last=$((first + 2))") != std::string::npos);
    CHECK(s.find("combine-2.sbatch") != std::string::npos);
    CHECK(s.find("#SBATCH --array=0-1\n") != std::string::npos);
    CHECK(s.find("first=$((SLURM_ARRAY_TASK_ID * 9)); last=$((first + 8))") != std::string::npos);
    CHECK(s.find("combine-3.sbatch") == std::string::npos);
    CHECK(s.find("merge '" + fs::absolute(dir / "grass.json").string() + "' --shard-dir '" + dir / "job/level-2'") != std::string::npos);
    // Few shards need no tree; --fan-in 0 never makes one.
    RunResult few = runPenumbra("slurm " + dir / "grass.json" + " --shards 10 --fan-in 0 --dir " + dir / "job" + " --dry-run");
    REQUIRE(few.exitCode == 0);
    CHECK(few.out.find("combine") == std::string::npos);
}

TEST_CASE("penumbra slurm finds the scene's errors and a budget too small for a shard before it submits", "[shards][cli]") {
    ScratchDir dir("slurm-checks");
    write(dir / "grass.json", grassScene("grass").dump());
    // Every array task would fail with these; the command fails first, with the bake's message,
    // and writes no job directory.
    write(dir / "bad.json", R"({"geometry": [{"type": "grid"}], "lights": [], "receivers": {"type": "camera", "eye": [0,3,5], "target": [0,0,0]}})");
    RunResult bad = runPenumbra("slurm " + dir / "bad.json" + " --shards 2 --dir " + dir / "job");
    CHECK(bad.exitCode == 1);
    CHECK(bad.err == "penumbra: error: " + dir / "bad.json" + ": lights: expected a non-empty array of lights\n");
    RunResult tiny = runPenumbra("slurm " + dir / "grass.json" + " --shards 2 --memory-budget 1K --dir " + dir / "job");
    CHECK(tiny.exitCode == 1);
    CHECK_THAT(tiny.err, Catch::StartsWith("penumbra: error: --memory-budget 1.00 KiB is too small for up to ") && Catch::Contains("is needed"));
    CHECK(lineCount(tiny.err) == 1);
    CHECK(runPenumbra("slurm " + dir / "grass.json" + " --shards 2 --memory-budget 0 --dir " + dir / "job").exitCode == 1);
    CHECK_FALSE(fs::exists(dir / "job"));
    // A budget the scan fits is left to each shard's exact check, as a bake does.
    CHECK(runPenumbra("slurm " + dir / "grass.json" + " --shards 2 --memory-budget 2G --dry-run --dir " + dir / "job").exitCode == 0);
}

TEST_CASE("penumbra slurm refuses values that would break a job script's #SBATCH lines", "[shards][cli]") {
    ScratchDir dir("slurm-values");
    write(dir / "grass.json", grassScene("grass").dump());
    // --dry-run: were a value let through, nothing is submitted.
    const std::string base = "slurm " + dir / "grass.json" + " --shards 2 --dry-run --dir " + dir / "job";
    // A line break would start a line of its own in the script (here a command); sbatch ends a
    // value at a space.
    RunResult newline = runPenumbra(base + " --partition \"$(printf 'a\\nrm -rf x')\"");
    CHECK(newline.exitCode == 1);
    CHECK(newline.err == "penumbra: error: --partition: must be one word without spaces or control characters, got 'a\\x0arm -rf x'\n");
    CHECK(runPenumbra(base + " --time '1 day'").exitCode == 1);
    RunResult path = runPenumbra(base.substr(0, base.find(" --dir")) + " --dir \"$(printf '" + dir / "a\\nb')\"");
    CHECK(path.exitCode == 1);
    CHECK_THAT(path.err, Catch::StartsWith("penumbra: error: --dir: a path with a line break"));
    CHECK_FALSE(fs::exists(dir / "job"));
    // A fan-in of one would combine each file alone: no tree, which 0 says.
    CHECK(runPenumbra(base + " --fan-in 1").err == "penumbra: error: --fan-in: must be 0 (no tree) or at least 2, got 1\n");
    CHECK(runPenumbra(base + " --partition gpu,cpu --time 1-12:00:00").exitCode == 0);
}

TEST_CASE("penumbra slurm quotes the job folder's log paths, names the shard count, and checks -o", "[shards][cli]") {
    ScratchDir dir("slurm-quoting");
    write(dir / "grass.json", grassScene("grass").dump());
    const std::string job = dir / "it's a job";
    RunResult r = runPenumbra("slurm " + dir / "grass.json" + " --shards 3 --dry-run --dir \"" + job + "\"");
    REQUIRE(r.exitCode == 0);
    // sbatch reads a double-quoted #SBATCH value as one word; unquoted, a space ended it there.
    CHECK(r.out.find("#SBATCH --output=\"" + job + "/logs/shard-%a.log\"\n") != std::string::npos);
    CHECK(r.out.find("#SBATCH --output=\"" + job + "/logs/merge.log\"\n") != std::string::npos);
    // The shard count is in the script, so `sbatch --array=2 shards.sbatch` reruns shard 2 of 3
    // (from the array's own count it baked the whole scene as shard 0 of 1).
    CHECK(r.out.find("--shard \"$SLURM_ARRAY_TASK_ID/3\"") != std::string::npos);
    // Slurm's file-name patterns would change a folder with '%' or a backslash.
    RunResult percent = runPenumbra("slurm " + dir / "grass.json" + " --shards 3 --dry-run --dir " + dir / "100%");
    CHECK(percent.exitCode == 1);
    CHECK_THAT(percent.err, Catch::StartsWith("penumbra: error: --dir: the job folder"));
    // The merge's -o is checked now, as a bake checks it, not by the merge job after every shard.
    RunResult ext = runPenumbra("slurm " + dir / "grass.json" + " --shards 3 --dry-run --dir " + dir / "job -o " + dir / "out.png");
    CHECK(ext.exitCode == 1);
    CHECK_THAT(ext.err, Catch::Contains("camera receivers write .exr files"));
    RunResult input = runPenumbra("slurm " + dir / "grass.json" + " --shards 3 --dry-run --dir " + dir / "job -o " + dir / "grass.json");
    CHECK(input.exitCode == 1);
    CHECK(runPenumbra("slurm " + dir / "grass.json" + " --shards 3 --dry-run --dir " + dir / "job -o " + dir / "out.exr").exitCode == 0);
    // The merge job gets the budget its --mem was sized for, as the shards do.
    RunResult budget = runPenumbra("slurm " + dir / "grass.json" + " --shards 3 --dry-run --memory-budget 2G --dir " + dir / "job");
    REQUIRE(budget.exitCode == 0);
    const std::string merge = budget.out.substr(budget.out.find("merge.sbatch"));
    CHECK(merge.find("--memory-budget '2G'") != std::string::npos);
}

TEST_CASE("an unusable --shard-dir or --checkpoint folder is refused before the work", "[shards][cli]") {
    // Found only when the first shard file was written, after the whole cast; a wrong -o was
    // refused at once.
    ScratchDir dir("shard-dir-check");
    write(dir / "grass.json", grassScene("grass").dump());
    write(dir / "afile", "not a folder");
    for (const std::string& options : {" --shard 0/2 --shard-dir " + dir / "afile/sh", " --checkpoint " + dir / "afile/ck"}) {
        INFO(options);
        RunResult r = runPenumbra("bake " + dir / "grass.json" + " -q -o " + dir / "o.exr" + options);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.err, Catch::Contains("afile/") && Catch::Contains("is not a directory"));
        CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
        CHECK_FALSE(fs::exists(dir / "o.exr"));
    }
}
