#pragma once
/// @file ShardCommands.h
/// @brief The command line of distributed and resumable bakes: `bake --shard I/N --shard-by ...
/// --shard-dir DIR`, `bake --checkpoint DIR` / `--resume DIR`, `penumbra merge SCENE --shard-dir
/// DIR [bake options]`, and `penumbra slurm SCENE --shards N` (docs/distributed.md).

#include "bake/Pipeline.h"

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace penumbra {

/// @brief The bake's shard and checkpoint flags, as typed.
struct ShardCli {
    std::string shard;   ///< "I/N", or "slurm": from SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT
    std::string shardBy = "auto";
    std::string shardDir;
    std::string checkpoint, resume;
    std::optional<double> checkpointEvery;  ///< seconds; unset: ShardSettings' default
    bool merge = false;  ///< set by `penumbra merge`
};

/// @brief Adds the shard and checkpoint flags to the `bake` subcommand.
void addShardOptions(CLI::App& bake, ShardCli& cli);

/// @brief The settings @p cli asks for.
/// @throw InputError for a bad `--shard`, `--shard-by`, a missing `--shard-dir`, or `--shard slurm`
/// outside a Slurm job array.
ShardSettings shardSettings(const ShardCli& cli);

/// @brief `penumbra merge ARGS` is `penumbra bake ARGS --merge`: a merge is a bake whose first
/// cast is read from shard files. Rewrites @p argv in place when it starts with `merge`.
/// @return the arguments to parse (pointing into @p storage).
std::vector<char*> rewriteMergeCommand(int argc, char** argv, std::vector<std::string>& storage);

/// @brief `penumbra slurm`'s options.
struct SlurmOptions {
    std::string scene;
    int shards = 4;
    std::string partition;
    std::string shardBy = "auto";
    std::string dir;           ///< scripts, logs and shard files; default SCENE_STEM.slurm beside the scene
    std::string output;        ///< -o of the merge (default: the scene's output)
    std::string memoryBudget;  ///< --memory-budget of every shard; Slurm's --mem follows from it
    std::string time;          ///< sbatch --time, optional
    std::string tmp;           ///< --tmp of every shard (node-local scratch)
    int threads = 1;           ///< --threads, and --cpus-per-task
    /// Most shard files one job reads: more shards than this are combined in a tree of jobs
    /// first (`penumbra combine`), so no merge node reads them all. 0: never.
    int fanIn = 32;
    bool dryRun = false;
};

/// @brief `penumbra combine`'s options: an inner node of a tree merge.
struct CombineOptions {
    std::vector<std::string> inputs;  ///< shard files, or directories of them
    std::string range;                ///< "A-B": the shards to combine (optional)
    std::string shardDir;             ///< where the combined file goes
    bool quiet = false;
};

/// @brief Adds the `combine` subcommand. @return it, to test whether it was chosen.
CLI::App* addCombineCommand(CLI::App& app, CombineOptions& options);

/// @brief ORs shard files into one (bake/shard/ShardFiles.h) and names it on stdout.
/// @throw InputError for files of different bakes, overlaps, gaps, damaged files.
void runCombine(const CombineOptions& options);

/// @brief Adds the `slurm` subcommand. @return it, to test whether it was chosen.
CLI::App* addSlurmCommand(CLI::App& app, SlurmOptions& options);

/// @brief Writes the job array and merge scripts; submits them unless --dry-run (then prints them).
/// Prints the job ids on stdout.
/// @throw InputError for bad options, unwritable scripts, or a failed sbatch.
void runSlurm(const SlurmOptions& options);

}  // namespace penumbra
