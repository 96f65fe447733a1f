#include "ShardCommands.h"
#include "BakeCommand.h"
#include "OptionForms.h"

#include "bake/BakeMemory.h"
#include "bake/BakeOutputs.h"
#include "bake/Scene.h"
#include "bake/shard/ShardFiles.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/Memory.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sys/wait.h>
#include <unistd.h>
#include <utility>

namespace penumbra {
namespace fs = std::filesystem;

void addShardOptions(CLI::App& bake, ShardCli& cli) {
    bake.add_option("--shard", cli.shard,
                    "cast shard I of N (I/N, or \"slurm\": SLURM_ARRAY_TASK_ID of SLURM_ARRAY_TASK_COUNT) and write its "
                    "masks to --shard-dir; penumbra merge makes the outputs")
        ->check(shardForm());
    bake.add_option("--shard-by", cli.shardBy, "how shards are cut: receivers, blockers or auto (default)")
        ->check(CLI::IsMember({"receivers", "blockers", "auto"}));
    bake.add_option("--shard-dir", cli.shardDir, "directory of shard files (written by --shard, read by merge)");
    bake.add_option("--checkpoint", cli.checkpoint,
                    "write a checkpoint per finished memory tile to this directory, and restore the ones found there");
    bake.add_option("--resume", cli.resume, "like --checkpoint, but a checkpoint that does not match is an error");
    bake.add_option("--checkpoint-every", cli.checkpointEvery,
                    "seconds of cast between checkpoints within a memory tile (default 300; 0: after every chunk)");
    bake.add_flag("--merge", cli.merge, "merge the shard files of --shard-dir (what `penumbra merge` runs)");
}

namespace {

uint32_t slurmNumber(const char* name) {
    const char* value = std::getenv(name);
    if (!value || !*value) fail("--shard", "slurm: {} is not set (not a task of a Slurm job array); give --shard I/N", name);
    char* end = nullptr;
    const unsigned long v = std::strtoul(value, &end, 10);
    if (*end || v > 65536) fail("--shard", "slurm: {}={} is not a task number", name, value);
    return uint32_t(v);
}

}  // namespace

ShardSettings shardSettings(const ShardCli& cli) {
    ShardSettings s;
    s.cut = parseShardCut(cli.shardBy, "--shard-by");
    s.dir = cli.shardDir;
    s.merge = cli.merge;
    if (cli.shard == "slurm") {
        const uint32_t first = std::getenv("SLURM_ARRAY_TASK_MIN") ? slurmNumber("SLURM_ARRAY_TASK_MIN") : 0;
        parseShardSpec(fmt::format("{}/{}", int64_t(slurmNumber("SLURM_ARRAY_TASK_ID")) - first,
                                   slurmNumber("SLURM_ARRAY_TASK_COUNT")),
                       "--shard slurm", s);
    } else if (!cli.shard.empty()) {
        parseShardSpec(cli.shard, "--shard", s);
    }
    if (s.merge && s.count) fail("--shard", "a merge reads every shard; leave --shard out");
    if ((s.merge || s.count) && s.dir.empty()) fail("--shard-dir", "is needed with {}", s.merge ? "merge" : "--shard");
    if (!cli.checkpoint.empty() && !cli.resume.empty()) fail("--resume", "give --checkpoint DIR or --resume DIR, not both");
    s.checkpointDir = cli.resume.empty() ? cli.checkpoint : cli.resume;
    s.resume = !cli.resume.empty();
    if (s.merge && !s.checkpointDir.empty()) fail("--checkpoint", "a merge casts no tiles to checkpoint");
    if (cli.checkpointEvery) {
        if (s.checkpointDir.empty()) fail("--checkpoint-every", "needs --checkpoint DIR or --resume DIR");
        if (!(*cli.checkpointEvery >= 0 && *cli.checkpointEvery <= 1e9))
            fail("--checkpoint-every", "must be a number of seconds in 0..1e9, got {}", *cli.checkpointEvery);
        s.checkpointEvery = *cli.checkpointEvery;
    }
    return s;
}

std::vector<char*> rewriteMergeCommand(int argc, char** argv, std::vector<std::string>& storage) {
    for (int i = 0; i < argc; ++i) storage.emplace_back(argv[i]);
    if (argc > 1 && storage[1] == "merge") storage[1] = "bake", storage.emplace_back("--merge");
    std::vector<char*> out;
    for (std::string& s : storage) out.push_back(s.data());
    return out;
}

CLI::App* addCombineCommand(CLI::App& app, CombineOptions& o) {
    CLI::App* c = app.add_subcommand("combine", "OR shard files of one bake into one (a tree merge's inner node): "
                                                "penumbra combine INPUT... --shard-dir OUT [--range A-B]");
    c->add_option("inputs", o.inputs, "shard files, or directories of them")->required();
    c->add_option("--range", o.range, "combine shards A to B (inclusive) of the inputs; default: all of them")->check(shardRangeForm());
    c->add_option("--shard-dir", o.shardDir, "directory for the combined file shards-A-B-of-N.pnpart")->required();
    c->add_flag("-q,--quiet", o.quiet, "print nothing");
    return c;
}

void runCombine(const CombineOptions& o) {
    std::optional<ShardRange> range;
    if (!o.range.empty()) range = parseShardRange(o.range, "--range");
    const std::string out = combineShardFiles(o.inputs, range, o.shardDir);
    if (!o.quiet) fmt::print("{}\n", out);
}

CLI::App* addSlurmCommand(CLI::App& app, SlurmOptions& o) {
    CLI::App* c = app.add_subcommand("slurm", "bake a scene as a Slurm job array of shards and a dependent merge job");
    c->add_option("scene", o.scene, "scene file (JSON), on a file system every node shares")->required();
    c->add_option("--shards", o.shards, "number of shards (array tasks), 1..65536")->required();
    c->add_option("--partition", o.partition, "Slurm partition");
    c->add_option("--shard-by", o.shardBy, "receivers, blockers or auto")->check(CLI::IsMember({"receivers", "blockers", "auto"}));
    c->add_option("--dir", o.dir, "shared directory for scripts, logs and shard files (default SCENE_STEM.slurm)");
    c->add_option("-o,--output", o.output, "the merge's output (default: the scene's)");
    c->add_option("--memory-budget", o.memoryBudget, "each shard's memory budget; Slurm's --mem follows from it")->check(byteSizeForm());
    c->add_option("--time", o.time, "sbatch --time of each task");
    c->add_option("--tmp", o.tmp, "each shard's --tmp: node-local scratch for bucket files");
    c->add_option("--threads", o.threads, "threads per task (and --cpus-per-task)");
    c->add_option("--fan-in", o.fanIn, "most shard files one job reads: more are combined in a tree of jobs first (0: never)");
    c->add_flag("--dry-run", o.dryRun, "print the scripts instead of submitting them");
    return c;
}

namespace {

/// @p s in single quotes for the shell.
std::string shellQuoted(const std::string& s) {
    std::string out = "'";
    for (char ch : s) out += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
    return out + "'";
}

std::string absolute(const std::string& path) { return fs::absolute(path).lexically_normal().string(); }

std::string selfPath() {
    std::error_code ec;
    fs::path self = fs::read_symlink("/proc/self/exe", ec);
    return ec ? std::string("penumbra") : self.string();
}

/// One sbatch script of a run, and the job it waits for (the one before it in the list).
struct SlurmScript {
    std::string name;    ///< file name in the job directory
    std::string text;
    std::string about;   ///< what it is, for the summary
};

/// The head every script shares: partition, time, CPUs and memory.
std::string scriptHead(const SlurmOptions& o) {
    std::string head = "#!/bin/bash\n";
    if (!o.partition.empty()) head += "#SBATCH --partition=" + o.partition + "\n";
    if (!o.time.empty()) head += "#SBATCH --time=" + o.time + "\n";
    head += fmt::format("#SBATCH --cpus-per-task={}\n", o.threads);
    if (!o.memoryBudget.empty()) {
        // The budget bounds the bake; the process itself (code, stacks, TBB) needs a little more.
        const uint64_t bytes = parseMemoryBudget(o.memoryBudget);
        head += fmt::format("#SBATCH --mem={}M\n", (bytes + bytes / 8) / (1 << 20) + 256);
    }
    return head;
}

/// The levels of combine jobs between the shards and the merge: level L (from 1) has
/// ceil(N / fanIn^L) tasks, task t combining shards [t fanIn^L, (t+1) fanIn^L), until the merge
/// has at most fanIn files to read. @return the shard span of each level's files.
std::vector<uint64_t> combineLevels(const SlurmOptions& o) {
    std::vector<uint64_t> spans;
    uint64_t files = uint64_t(o.shards), span = 1;
    while (o.fanIn >= 2 && files > uint64_t(o.fanIn)) {
        span *= uint64_t(o.fanIn);
        files = (uint64_t(o.shards) + span - 1) / span;
        spans.push_back(span);
    }
    return spans;
}

/// @p path as an `#SBATCH` value: in double quotes, which sbatch reads as one word (a folder with a
/// space or an apostrophe), with a double quote escaped. checkJobFolder() keeps out what its
/// file-name patterns would change.
std::string sbatchQuoted(const std::string& path) {
    std::string out = "\"";
    for (char c : path) out += c == '"' ? std::string("\\\"") : std::string(1, c);
    return out + "\"";
}

/// Refuses a job folder whose name sbatch's `--output` patterns would change: '%' starts a
/// pattern (%a, %j) and a backslash turns them all off.
void checkJobFolder(const std::string& dir) {
    if (dir.find_first_of("%\\") != std::string::npos)
        fail("--dir", "the job folder \"{}\" holds a '%' or a backslash, which Slurm's --output patterns would change; "
             "give --dir a folder without them", printableLine(dir));
}

std::vector<SlurmScript> makeScripts(const SlurmOptions& o, const std::string& dir) {
    const std::string exe = shellQuoted(selfPath()), scene = shellQuoted(absolute(o.scene));
    const std::string head = scriptHead(o);
    const std::string budget = o.memoryBudget.empty() ? "" : " --memory-budget " + shellQuoted(o.memoryBudget);
    const std::string tmp = o.tmp.empty() ? " --tmp \"${TMPDIR:-/tmp}\"" : " --tmp " + shellQuoted(o.tmp);
    std::vector<SlurmScript> scripts;
    scripts.push_back({"shards.sbatch",
                       head + fmt::format("#SBATCH --job-name=penumbra-shards\n#SBATCH --array=0-{}\n#SBATCH --output={}\n"
                                          "set -eu\n"
                                          "exec {} bake {} --shard \"$SLURM_ARRAY_TASK_ID/{}\" --shard-by {} --shard-dir {} --threads {}{}{} --quiet\n",
                                          o.shards - 1, sbatchQuoted(dir + "/logs/shard-%a.log"), exe, scene, o.shards, o.shardBy, shellQuoted(dir + "/shards"), o.threads, budget, tmp),
                       fmt::format("shards job {{}} ({} tasks)", o.shards)});
    std::string from = dir + "/shards";
    const std::vector<uint64_t> spans = combineLevels(o);
    for (size_t level = 1; level <= spans.size(); ++level) {
        const uint64_t span = spans[level - 1], tasks = (uint64_t(o.shards) + span - 1) / span;
        const std::string to = fmt::format("{}/level-{}", dir, level);
        scripts.push_back({fmt::format("combine-{}.sbatch", level),
                           head + fmt::format("#SBATCH --job-name=penumbra-combine-{}\n#SBATCH --array=0-{}\n"
                                              "#SBATCH --output={}\n"
                                              "set -eu\n"
                                              "first=$((SLURM_ARRAY_TASK_ID * {})); last=$((first + {}))\n"
                                              "if [ \"$last\" -ge {} ]; then last={}; fi\n"
                                              "exec {} combine {} --range \"$first-$last\" --shard-dir {} --quiet\n",
                                              level, tasks - 1, sbatchQuoted(fmt::format("{}/logs/combine-{}-%a.log", dir, level)), span, span - 1, o.shards, o.shards - 1, exe,
                                              shellQuoted(from), shellQuoted(to)),
                           fmt::format("combine job {{}} (level {}: {} tasks of {} shards)", level, tasks, span)});
        from = to;
    }
    const std::string output = o.output.empty() ? "" : " -o " + shellQuoted(absolute(o.output));
    scripts.push_back({"merge.sbatch",
                       head + fmt::format("#SBATCH --job-name=penumbra-merge\n#SBATCH --output={}\n"
                                          "set -eu\n"
                                          "exec {} merge {} --shard-dir {}{} --stats {} --threads {}{}{} --quiet\n",
                                          sbatchQuoted(dir + "/logs/merge.log"), exe, scene, shellQuoted(from), output, shellQuoted(dir + "/merge-stats.json"), o.threads, budget, tmp),
                       "merge job {}"});
    return scripts;
}

/// Runs `sbatch --parsable ARGS SCRIPT` and returns the job id it prints.
std::string submit(const std::string& args, const std::string& script) {
    const std::string command = "sbatch --parsable " + args + shellQuoted(script) + " 2>&1";
    FILE* pipe = popen(command.c_str(), "r");
    if (!pipe) fail("sbatch", "cannot run: {}", std::strerror(errno));
    std::string out;
    std::array<char, 256> buffer;
    while (size_t n = std::fread(buffer.data(), 1, buffer.size(), pipe)) out.append(buffer.data(), n);
    const int status = pclose(pipe);
    while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
    if (status != 0 || out.empty() || out.find_first_not_of("0123456789;") != std::string::npos)
        fail(script, "sbatch failed: {}", out.empty() ? "no output" : out.substr(0, out.find('\n')));
    return out.substr(0, out.find(';'));
}

/// Values that go into the scripts' `#SBATCH` lines as they are: a line break there would start a
/// line of its own (a shell command, in the script's body), and sbatch ends a value at a space.
void checkScriptValues(const SlurmOptions& o) {
    requireInRange("--shards", o.shards, 1, 65536);
    requireInRange("--threads", o.threads, 1, kMaxThreads);
    requireInRange("--fan-in", o.fanIn, 0, 65536);
    // A combine of one file is that file: 1 would mean no tree, which 0 says.
    if (o.fanIn == 1) fail("--fan-in", "must be 0 (no tree) or at least 2, got 1");
    const auto control = [](const std::string& v) { return std::any_of(v.begin(), v.end(), [](char c) { return uint8_t(c) < 0x20 || c == 0x7f; }); };
    const auto space = [](const std::string& v) { return v.find(' ') != std::string::npos; };
    for (const auto& [option, value] : {std::pair{"--partition", &o.partition}, std::pair{"--time", &o.time}})
        if (control(*value) || space(*value)) fail(option, "must be one word without spaces or control characters, got '{}'", printableLine(*value));
    for (const auto& [option, value] : {std::pair{"--dir", &o.dir}, std::pair{"--tmp", &o.tmp}, std::pair{"scene", &o.scene}, std::pair{"--output", &o.output}})
        if (control(*value)) fail(option, "a path with a line break or control character cannot go into a job script, got '{}'", printableLine(*value));
}

/// What every shard would find wrong before its work, found now, on the submitting host, instead
/// of by N array tasks on the nodes: the scene's errors (the scene is parsed), and a
/// --memory-budget below what a shard's scan pass needs (every shard scans the whole scene; its
/// files are opened as a bake opens them, which reads an OBJ through once to check it). A budget
/// that passes may still fail a shard's exact check after its scan.
void checkShardBakes(const SlurmOptions& o) {
    SceneDesc scene = loadScene(o.scene);
    // The merge job's outputs, as a bake checks them before its work: the kind's extension, a
    // file the scene reads, a folder that cannot be written.
    if (!o.output.empty()) scene.output = absolute(o.output), scene.outputFromScene = false;
    validateReceiverKind(scene.receivers, scene);
    checkBakeOutputs(scene, "", "");
    if (o.memoryBudget.empty()) return;
    BakeBudget budget;
    budget.bytes = parseMemoryBudget(o.memoryBudget);
    budget.threads = std::max(1, o.threads);
    MemoryDemand demand;
    openCheckedBeforeScan(scene, *makeReceiverKind(scene.receivers, scene), budget, MaskKeeping{true}, /*quiet=*/false, demand);
}

}  // namespace

void runSlurm(const SlurmOptions& o) {
    checkScriptValues(o);
    if (!fs::is_regular_file(o.scene)) fail(o.scene, "not a scene file");
    checkShardBakes(o);
    if (!o.output.empty()) requireOutputFolder("--output", o.output);  // now, not when the merge job runs
    const fs::path scene = fs::absolute(o.scene);
    const std::string dir = absolute(o.dir.empty() ? (scene.parent_path() / (scene.stem().string() + ".slurm")).string() : o.dir);
    checkJobFolder(dir);
    const std::vector<SlurmScript> scripts = makeScripts(o, dir);
    if (o.dryRun) {
        for (size_t i = 0; i < scripts.size(); ++i)
            fmt::print("# {}/{}{}\n{}{}", dir, scripts[i].name, i ? " (sbatch --dependency=afterok:PREVIOUS_JOB)" : "",
                       scripts[i].text, i + 1 < scripts.size() ? "\n" : "");
        return;
    }
    std::error_code ec;
    fs::create_directories(dir + "/logs", ec);
    fs::create_directories(dir + "/shards", ec);
    if (ec) fail(dir, "cannot create the job directory: {}", ec.message());
    const auto bytes = [](const std::string& t) { return std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(t.data()), t.size()); };
    for (const SlurmScript& s : scripts) writeFileAtomically(dir + "/" + s.name, bytes(s.text));
    // Each job waits for the whole array before it: a level combines what the one before wrote.
    std::string previous;
    for (const SlurmScript& s : scripts) {
        previous = submit(previous.empty() ? "" : "--dependency=afterok:" + previous + " ", dir + "/" + s.name);
        fmt::print(fmt::runtime(s.about + "\n"), previous);
    }
    std::fflush(stdout);
}

}  // namespace penumbra
