/// @file main.cpp
/// @brief The `penumbra` command-line tool: bake, compare, info, convert, generate, bench.

#include "Compare.h"
#include "Generate.h"
#include "GeneratorBench.h"
#include "MethodsBench.h"
#include "ShardCommands.h"
#include "TableBench.h"

#include "bake/LibraryErrors.h"
#include "bake/Pipeline.h"
#include "bake/cast/Caster.h"
#include "bake/Scene.h"
#include "bake/shard/ShardRun.h"
#include "bake/kinds/VolumeKind.h"
#include "procedural/Generators.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Diagnostics.h"
#include "stream/util/Error.h"
#include "stream/GeometryFile.h"
#include "stream/util/InputFile.h"
#include "stream/util/Memory.h"
#include "stream/util/SafePath.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <exception>
#include <utility>
#include <vector>
#include <sstream>

using namespace penumbra;

namespace {

/// Applies `--disable a,b,c` to the scene's cast options.
void disableOptimizations(CastOptions& o, const std::vector<std::string>& names) {
    for (const std::string& name : names) {
        if (name == "umbra") o.umbraBits = false;
        else if (name == "active-planes") o.activePlanes = false;
        else if (name == "lazy-volumes") o.lazyVolumes = false;
        else if (name == "lazy-masks") o.lazyMasks = false;
        else if (name == "rebuild") o.rebuild = false;
        else if (name == "sort") o.sortBlockers = false;
        else if (name == "sample-table") o.sampleTable = false;
        else if (name == "closed-casters") o.closedCasters = false;
        else if (name == "cull-before-spill") o.cullBeforeSpill = false;
        else if (name == "all")
            o.umbraBits = o.activePlanes = o.lazyVolumes = o.lazyMasks = o.rebuild = o.sortBlockers = o.sampleTable =
                o.closedCasters = o.cullBeforeSpill = false;
        else
            throw InputError("--disable: unknown optimization \"" + name +
                             "\" (known: umbra, active-planes, lazy-volumes, lazy-masks, rebuild, sort, sample-table, closed-casters, cull-before-spill, all)");
    }
}

/// Writes a command's result to stdout; a failed write (a full disk, a closed pipe) is an error,
/// since the result is what the command is for.
void printResult(const std::string& text) {
    if (std::fwrite(text.data(), 1, text.size(), stdout) != text.size() || std::fflush(stdout) != 0)
        throw InputError(fmt::format("stdout: write failed: {}", std::strerror(errno)));
}

/// An option given with an empty value ("-o ''") is a mistake, never "not given".
void requireNonEmpty(const CLI::Option* option, const std::string& value) {
    if (option->count() > 0 && value.empty()) throw InputError(option->get_name() + ": must not be empty");
}

/// Prints the one line for an exception that ended a command and returns the exit code: 1 for
/// errors in the input or the environment (a library's included), 70 for penumbra's own bugs.
/// @param context the command's main input, named when the library did not.
int reportError(std::exception_ptr error, const std::string& context) {
    const std::string prefix = context.empty() ? "penumbra: error: " : "penumbra: error: " + context + ": ";
    try {
        std::rethrow_exception(error);
    } catch (const InputError& e) {
        printDiagnostic(fmt::format("penumbra: error: {}\n", e.what()));
    } catch (const std::bad_alloc&) {
        printDiagnostic("penumbra: error: out of memory (try --memory-budget or fewer receivers)\n");
    } catch (const std::length_error& e) {  // a size from the input beyond what a container can hold
        printDiagnostic(fmt::format("{}too large to hold in memory ({})\n", prefix, e.what()));
    } catch (const std::exception& e) {
        if (std::optional<std::string> message = libraryErrorMessage(e)) {
            printDiagnostic(prefix + *message + "\n");
            return 1;
        }
        printDiagnostic(fmt::format("penumbra: internal error: {}\n", e.what()));
        return 70;
    } catch (...) {
        printDiagnostic("penumbra: internal error: an unknown exception\n");
        return 70;
    }
    return 1;
}

/// A command-line usage error exits 2 (README, "Exit codes"); --help and --version exit 0. An
/// unknown first word is named as an unknown command, with the commands there are.
int reportUsageError(CLI::App& app, const CLI::ParseError& e, int argc, char** argv) {
    if (e.get_exit_code() == 0) return app.exit(e);
    std::vector<std::string> commands;
    for (const CLI::App* command : app.get_subcommands([](CLI::App*) { return true; })) commands.push_back(command->get_name());
    const std::string first = argc > 1 ? argv[1] : "";
    if (!first.empty() && first[0] != '-' && std::find(commands.begin(), commands.end(), first) == commands.end()) {
        printDiagnostic(fmt::format("penumbra: error: unknown command '{}' (commands: {}; see penumbra --help)\n", first,
                                    fmt::join(commands, ", ")));
        return 2;
    }
    app.exit(e);
    return 2;
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

    std::string scenePath, output, method = "hpc", statsPath, dumpDir;
    int threads = 0;
    bool quiet = false;
    std::vector<std::string> disabled;
    CLI::App* bake = app.add_subcommand("bake", "bake soft shadows for a scene file");
    bake->add_option("scene", scenePath, "scene file (JSON)")->required();
    CLI::Option* outputOption = bake->add_option("-o,--output", output, "output file (overrides the scene's \"output\")");
    std::string methods;
    for (const std::string& name : casterNames()) methods += (methods.empty() ? "" : ", ") + name;
    bake->add_option("--method", method, "shadow method: " + methods + " (default hpc)");
    bake->add_option("--threads", threads, "worker threads (default: all cores)");
    CLI::Option* statsOption = bake->add_option("--stats", statsPath, "write JSON stats to this file");
    CLI::Option* dumpOption = bake->add_option("--dump", dumpDir,
                                               "write receivers.npy, samples.npy, masks.npy and rule.json to this directory");
    bake->add_option("--disable", disabled,
                     "switch optimizations off: umbra, active-planes, lazy-volumes, lazy-masks, rebuild, sort, sample-table, closed-casters, "
                     "cull-before-spill, all")
        ->delimiter(',');
    bake->add_flag("-q,--quiet", quiet, "no progress on stderr");
    std::string simd;
    bake->add_option("--simd", simd, "hard-shadow test kernels: auto (default), avx2, sse2 or scalar; same bits for all");
    std::string sampleTable;
    bake->add_option("--sample-table", sampleTable, "on or off: sample mask tables (overrides bake.sample_table)")
        ->check(CLI::IsMember({"on", "off"}));
    std::string closedCasters, embreeFilter;
    bake->add_option("--embree-filter", embreeFilter,
                     "--method embree: apply the blocking rule to every hit (on, default) or take Embree's native answer (off)")
        ->check(CLI::IsMember({"on", "off"}));
    bake->add_option("--closed-casters", closedCasters,
                     "on or off: skip closed surfaces' triangles that face away from the light (overrides "
                     "bake.closed_casters)")
        ->check(CLI::IsMember({"on", "off"}));
    std::string visibilityPath;
    bake->add_option("--visibility", visibilityPath, "write every receiver's visible fraction as a float32 .npy");
    int mapResolution = 0;
    double mapBias = -1;
    bake->add_option("--penumbra-map-resolution", mapResolution, "penumbra-map: texels per side of a shadow map (overrides bake.penumbra_map_resolution)")
        ->check(CLI::Range(16, 16384));
    bake->add_option("--penumbra-map-bias", mapBias, "penumbra-map: depth bias in texels (overrides bake.penumbra_map_bias)")
        ->check(CLI::Range(0.0, 1e6));
    std::string memoryBudget, tmpDir;
    bool keepBuckets = false;
    CLI::Option* budgetOption =
        bake->add_option("--memory-budget", memoryBudget, "bound on bake memory, e.g. 256M or 2G; receivers are tiled to fit");
    CLI::Option* tmpOption = bake->add_option("--tmp", tmpDir, "directory for temporary bucket files (default: the system temp dir)");
    bake->add_flag("--keep-buckets", keepBuckets, "keep the bucket files (for debugging)");
    ShardCli shardCli;
    addShardOptions(*bake, shardCli);
    SlurmOptions slurmOptions;
    CLI::App* slurm = addSlurmCommand(app, slurmOptions);
    app.add_subcommand("merge", "merge shard files into a bake's outputs: penumbra merge SCENE --shard-dir DIR [bake options]")
        ->allow_extras();

    CompareOptions compareOptions;
    CLI::App* compare = app.add_subcommand("compare", "compare two --dump directories relation by relation");
    compare->add_option("dump_a", compareOptions.dirA)->required();
    compare->add_option("dump_b", compareOptions.dirB)->required();
    compare->add_option("--scene", compareOptions.scenePath, "scene file: classify mismatches as ties of the blocking rule");
    compare->add_option("--list", compareOptions.list, "print this many mismatches with their verdicts (default 10)");
    compare->add_option("--mismatches", compareOptions.mismatchesCsv, "write every mismatch and its verdict as CSV");

    std::string infoPath;
    CLI::App* info = app.add_subcommand("info", "print triangle count, bounds and total area of a geometry file");
    info->add_option("file", infoPath)->required();

    std::string convertIn, convertOut;
    CLI::App* convert = app.add_subcommand("convert", "convert geometry between .obj, .gltf/.glb and .ptri");
    convert->add_option("input", convertIn)->required();
    convert->add_option("output", convertOut)->required();

    std::string sliceIn, sliceOut, sliceGrid = "visibility", sliceAxis = "y";
    double sliceAt = 0;
    CLI::App* slice = app.add_subcommand("vdb-slice", "render an axis-aligned slice of a .vdb float grid to a PNG");
    slice->add_option("input", sliceIn)->required();
    slice->add_option("output", sliceOut)->required();
    slice->add_option("--axis", sliceAxis, "x, y or z")->check(CLI::IsMember({"x", "y", "z"}));
    slice->add_option("--at", sliceAt, "world coordinate of the slice along the axis");
    slice->add_option("--grid", sliceGrid, "float grid name");

    GenerateOptions generateOptions;
    CLI::App* generate = addGenerateCommand(app, generateOptions);
    bool allowOutside = false;
    for (CLI::App* command : {bake, generate, info, convert})
        command->add_flag("--allow-outside-uris", allowOutside,
                          "let scenes and glTF files name files outside their own directory");

    BenchGeneratorsOptions benchGeneratorsOptions;
    CLI::App* bench = app.add_subcommand("bench", "benchmarks");
    bench->require_subcommand(1);
    CLI::App* benchGenerators = addBenchGeneratorsCommand(*bench, benchGeneratorsOptions);
    BenchTableOptions benchTableOptions;
    CLI::App* benchTable = addBenchTableCommand(*bench, benchTableOptions);
    BenchMethodsOptions benchMethodsOptions;
    CLI::App* benchMethods = addBenchMethodsCommand(*bench, benchMethodsOptions);

    std::vector<std::string> argumentStorage;  // `merge` is a bake of shard files (ShardCommands.h)
    std::vector<char*> arguments = rewriteMergeCommand(argc, argv, argumentStorage);
    try {
        app.parse(int(arguments.size()), arguments.data());
    } catch (const CLI::ParseError& e) {
        return reportUsageError(app, e, argc, argv);
    }

    // Inputs of the command are recorded, so that no output replaces one (InputFile.h).
    InputScope inputs;
    setOutsidePathsAllowed(allowOutside);
    std::string context;  // the command's main input, for errors a library throws
    try {
        if (*bake) {
            context = scenePath;
            for (auto [option, value] : {std::pair{outputOption, &output}, {statsOption, &statsPath},
                                         {dumpOption, &dumpDir}, {tmpOption, &tmpDir}, {budgetOption, &memoryBudget}})
                requireNonEmpty(option, *value);
            SceneDesc scene = loadScene(scenePath);
            if (outputOption->count()) scene.output = output, scene.outputFromScene = false;
            disableOptimizations(scene.options, disabled);
            if (!simd.empty()) scene.options.simd = parseSimdLevel(simd, "--simd");
            if (!sampleTable.empty()) scene.options.sampleTable = sampleTable == "on";
            if (!closedCasters.empty()) scene.options.closedCasters = closedCasters == "on";
            if (!embreeFilter.empty()) scene.options.embreeRuleFilter = embreeFilter == "on";
            if (mapResolution > 0) scene.bakeOptions["penumbra_map_resolution"] = mapResolution;
            if (mapBias >= 0) scene.bakeOptions["penumbra_map_bias"] = mapBias;
            BakeSettings settings;
            settings.method = casterEntry(method).name;
            if (threads < 0 || threads > kMaxThreads)
                throw InputError(fmt::format("--threads: must be in 0..{} (0: all cores), got {}", kMaxThreads, threads));
            settings.threads = threads;
            settings.statsPath = statsPath;
            settings.dumpDir = dumpDir;
            settings.visibilityPath = visibilityPath;
            settings.quiet = quiet;
            if (budgetOption->count()) {
                settings.memoryBudget = parseByteSize(memoryBudget, "--memory-budget");
                if (settings.memoryBudget == 0)
                    throw InputError("--memory-budget: must be more than 0 (leave it out for no budget)");
            }
            settings.tmpDir = tmpDir;
            settings.keepBuckets = keepBuckets;
            settings.shard = shardSettings(shardCli);
            nlohmann::json stats = runBake(scene, settings);
            if (!quiet)
                fmt::print(stderr, "penumbra: {} receivers, {} samples, {} triangles, {:.2f} s -> {}\n",
                           stats["receivers"].get<uint64_t>(), stats["light_samples"].get<int>(),
                           stats["counters"]["triangles_read"].get<uint64_t>(),
                           stats["table2"]["total_time_s"].get<double>(),
                           settings.shard.casting() ? shardFilePath(settings.shard.dir, settings.shard.index, settings.shard.count)
                                                    : scene.output);
        } else if (*slurm) {
            context = slurmOptions.scene;
            runSlurm(slurmOptions);
        } else if (*compare) {
            context = compareOptions.dirA;
            CompareResult r = compareDumps(compareOptions);
            printResult(fmt::format("receivers {}\nsamples {}\nrelations {}\nblocked_a {}\nblocked_b {}\nonly_a {}\nonly_b {}\n",
                                    r.receivers, r.samples, r.relations, r.blockedA, r.blockedB, r.onlyA, r.onlyB));
            if (r.classified) {
                printResult(fmt::format("ties {}\nunexplained {}\n", r.ties, r.unexplained()));
                for (const auto& [quantity, count] : r.tiesByQuantity) printResult(fmt::format("ties_{} {}\n", quantity, count));
            }
            bool same = r.classified ? r.unexplained() == 0 : r.onlyA + r.onlyB == 0;
            return same ? 0 : 3;
        } else if (*info) {
            context = infoPath;
            TriangleSourcePtr source = openGeometryFile(infoPath);
            GeometryInfo g = scanGeometry(*source);
            printResult(fmt::format("triangles {}\nbounds_min {} {} {}\nbounds_max {} {} {}\narea {}\n", g.triangles, g.lo.x,
                                    g.lo.y, g.lo.z, g.hi.x, g.hi.y, g.hi.z, g.area));
        } else if (*generate) {
            context = generateOptions.scene;
            runGenerate(generateOptions);
        } else if (*benchGenerators) {
            runBenchGenerators(benchGeneratorsOptions);
        } else if (*benchTable || *benchMethods) {
            std::string commandLine = "penumbra";  // recorded in the benchmark's outputs
            for (int i = 1; i < argc; ++i) commandLine += std::string(" ") + argv[i];
            if (*benchTable) runBenchTable(benchTableOptions, commandLine);
            else runBenchMethods(benchMethodsOptions, commandLine);
        } else if (*slice) {
            context = sliceIn;
            writeVolumeSlicePng(sliceIn, sliceOut, sliceGrid, sliceAxis[0], sliceAt);
        } else if (*convert) {
            context = convertIn;
            TriangleSourcePtr source = openGeometryFile(convertIn);
            convertGeometry(*source, convertOut);
        }
    } catch (...) {
        return reportError(std::current_exception(), context);
    }
    return 0;
}
