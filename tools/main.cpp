/// @file main.cpp
/// @brief The `penumbra` command-line tool: each command's options and run live in their own
/// file (BakeCommand, FileCommands, Generate, ShardCommands, the benches); this file only wires
/// them into one CLI and maps how a command ends to its exit code (CliErrors.h).

#include "BakeCommand.h"
#include "CliErrors.h"
#include "FileCommands.h"
#include "MakeExample.h"
#include "Generate.h"
#include "GeneratorBench.h"
#include "MethodsBench.h"
#include "ShardCommands.h"
#include "TableBench.h"

#include "bake/Scene.h"
#include "bake/TbbControl.h"
#include "procedural/Generators.h"
#include "stream/util/Diagnostics.h"
#include "stream/util/InputFile.h"
#include "stream/util/SafePath.h"
#include "stream/util/TempRegistry.h"

#include <CLI/CLI.hpp>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

using namespace penumbra;

namespace {

/// Every command's options; the CLI parses into them.
struct Commands {
    BakeCommand bake;
    CLI::App* bakeCommand = nullptr;
    SlurmOptions slurm;
    CLI::App* slurmCommand = nullptr;
    CombineOptions combine;
    CLI::App* combineCommand = nullptr;
    FileCommands files;
    GenerateOptions generate;
    CLI::App* generateCommand = nullptr;
    MakeExampleOptions makeExample;
    CLI::App* makeExampleCommand = nullptr;
    BenchGeneratorsOptions benchGenerators;
    BenchTableOptions benchTable;
    BenchMethodsOptions benchMethods;
    CLI::App *benchGeneratorsCommand = nullptr, *benchTableCommand = nullptr, *benchMethodsCommand = nullptr;
    bool allowOutside = false;
};

void addCommands(CLI::App& app, Commands& c) {
    c.bakeCommand = addBakeCommand(app, c.bake);
    c.slurmCommand = addSlurmCommand(app, c.slurm);
    c.combineCommand = addCombineCommand(app, c.combine);
    app.add_subcommand("merge", "merge shard files into a bake's outputs: penumbra merge SCENE --shard-dir DIR [bake options]")
        ->allow_extras();
    addFileCommands(app, c.files);
    c.generateCommand = addGenerateCommand(app, c.generate);
    c.makeExampleCommand = addMakeExampleCommand(app, c.makeExample);
    for (CLI::App* command : {c.bakeCommand, c.generateCommand, c.files.infoCommand, c.files.convertCommand, c.files.compareCommand})
        command->add_flag("--allow-outside-uris", c.allowOutside, "let scenes and glTF files name files outside their own directory");
    CLI::App* bench = app.add_subcommand("bench", "benchmarks");
    bench->require_subcommand(1);
    c.benchGeneratorsCommand = addBenchGeneratorsCommand(*bench, c.benchGenerators);
    c.benchTableCommand = addBenchTableCommand(*bench, c.benchTable);
    c.benchMethodsCommand = addBenchMethodsCommand(*bench, c.benchMethods);
}

/// Runs the chosen command. @param context receives its main input, for errors a library throws.
int runCommand(const Commands& c, int argc, char** argv, std::string& context) {
    if (*c.bakeCommand) return context = c.bake.scenePath, runBakeCommand(c.bake), 0;
    if (*c.slurmCommand) return context = c.slurm.scene, runSlurm(c.slurm), 0;
    if (*c.combineCommand) return context = c.combine.shardDir, runCombine(c.combine), 0;
    if (*c.generateCommand) return context = c.generate.scene, runGenerate(c.generate), 0;
    if (*c.makeExampleCommand) return context = c.makeExample.output, runMakeExample(c.makeExample), 0;
    if (*c.benchGeneratorsCommand) return runBenchGenerators(c.benchGenerators), 0;
    if (*c.benchTableCommand || *c.benchMethodsCommand) {
        std::string commandLine = "penumbra";  // recorded in the benchmark's outputs
        for (int i = 1; i < argc; ++i) commandLine += std::string(" ") + argv[i];
        if (*c.benchTableCommand) runBenchTable(c.benchTable, commandLine);
        else runBenchMethods(c.benchMethods, commandLine);
        return 0;
    }
    return runFileCommand(c.files, context).value_or(0);
}

}  // namespace

int main(int argc, char** argv) {
    // Diagnostics must never change how a run ends: stderr may be full or closed, stdout a pipe
    // that `head` has left.
    makeStandardStreamsSafe();
    // A file-size limit (prlimit --fsize) must surface as EFBIG from write(), which the writers
    // report with the file name, instead of killing the process with SIGXFSZ.
    std::signal(SIGXFSZ, SIG_IGN);
    installCleanupSignalHandlers();
    registerFileSourceTypes();
    registerProceduralGenerators();

    CLI::App app{"penumbra: out-of-core soft-shadow baker (hierarchical penumbra casting)"};
    app.require_subcommand(1);
    app.set_version_flag("--version", "penumbra " PENUMBRA_VERSION);
    Commands commands;
    addCommands(app, commands);

    std::vector<std::string> argumentStorage;  // `merge` is a bake of shard files (ShardCommands.h)
    std::vector<char*> arguments = rewriteMergeCommand(argc, argv, argumentStorage);
    try {
        app.parse(int(arguments.size()), arguments.data());
    } catch (const CLI::ParseError& e) {
        return reportUsageError(app, e, argc, argv);
    }

    InputScope inputs;  // inputs of the command are recorded, so that no output replaces one (InputFile.h)
    setOutsidePathsAllowed(commands.allowOutside);
    std::string context;
    int code = 0;
    try {
        code = runCommand(commands, argc, argv, context);
    } catch (...) {
        code = reportError(std::current_exception(), context);
    }
    if (threadStartFailed()) {  // TBB's exit handlers would wait for a worker that never started
        std::fflush(nullptr);
        std::_Exit(code);
    }
    return code;
}
