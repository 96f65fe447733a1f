#include "BakeCommand.h"
#include "OptionForms.h"

#include "bake/BakeOutputs.h"
#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "bake/cast/Caster.h"
#include "bake/shard/ShardRun.h"
#include "stream/util/Error.h"
#include "stream/util/Memory.h"
#include "stream/util/Progress.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <utility>

namespace penumbra {
namespace {

constexpr const char* kOptimizations =
    "umbra, active-planes, lazy-volumes, lazy-masks, rebuild, sort, sample-table, closed-casters, cull-before-spill, defer-group-volumes, footprints, alpha-bounds, front-plane, all";

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
        else if (name == "defer-group-volumes") o.groupVolumesAfter = 0;
        else if (name == "footprints") o.footprints = false;
        else if (name == "alpha-bounds") o.alphaBounds = false;
        else if (name == "front-plane") o.frontPlane = false;
        else if (name == "all")
            o.umbraBits = o.activePlanes = o.lazyVolumes = o.lazyMasks = o.rebuild = o.sortBlockers = o.sampleTable =
                o.closedCasters = o.cullBeforeSpill = o.footprints = o.alphaBounds = o.frontPlane = false,
            o.groupVolumesAfter = 0;
        else
            throw InputError(fmt::format("--disable: unknown optimization \"{}\" (known: {})", name, kOptimizations));
    }
}

/// An option given with an empty value ("-o ''") is a mistake, never "not given".
void requireNonEmpty(const CLI::Option* option, const std::string& value) {
    if (option->count() > 0 && value.empty()) throw InputError(option->get_name() + ": must not be empty");
}

void addCastOptions(CLI::App& bake, BakeCommand& c) {
    bake.add_option("--disable", c.disabled, std::string("switch optimizations off: ") + kOptimizations)->delimiter(',');
    bake.add_option("--simd", c.simd, "the cast's SIMD kernels: auto (default), avx2, sse2 or scalar; same bits for all");
    bake.add_option("--sample-table", c.sampleTable, "on or off: sample mask tables (overrides bake.sample_table)")
        ->check(CLI::IsMember({"on", "off"}));
    bake.add_option("--embree-filter", c.embreeFilter,
                    "--method embree: apply the blocking rule to every hit (on, default) or take Embree's native answer (off)")
        ->check(CLI::IsMember({"on", "off"}));
    bake.add_option("--closed-casters", c.closedCasters,
                    "on or off: skip closed surfaces' triangles that face away from the light (overrides bake.closed_casters)")
        ->check(CLI::IsMember({"on", "off"}));
    c.mapResolutionOption = bake.add_option("--penumbra-map-resolution", c.mapResolution,
                                            "penumbra-map: texels per side of a shadow map, 16..16384 (overrides "
                                            "bake.penumbra_map_resolution)");
    c.mapBiasOption = bake.add_option("--penumbra-map-bias", c.mapBias,
                                      "penumbra-map: depth bias in texels, 0..1e6 (overrides bake.penumbra_map_bias)");
    bake.add_option("--penumbra-map-lookup", c.mapLookup,
                    "penumbra-map: backprojection (default: inner and outer penumbrae) or wyman-hansen (the paper's outer penumbrae; "
                    "overrides bake.penumbra_map_lookup)")
        ->check(CLI::IsMember({"backprojection", "wyman-hansen"}));
    c.mapTapsOption = bake.add_option(
        "--penumbra-map-taps", c.mapTaps,
        "penumbra-map backprojection: texels read each side of a receiver, 1..8 (default 3; overrides bake.penumbra_map_taps)");
}

/// The files a bake wrote, for its summary line: each one, up to a few, then how many more.
std::string writtenFiles(const nlohmann::json& stats) {
    const std::vector<std::string> files = stats.value("outputs_written", std::vector<std::string>{});
    if (files.empty()) return "no files written";
    constexpr size_t kNamed = 4;
    std::string text;
    for (size_t i = 0; i < std::min(files.size(), kNamed); ++i) text += (i ? ", " : "") + files[i];
    if (files.size() > kNamed) text += fmt::format(" and {} more", files.size() - kNamed);
    return text;
}

/// The scene with the command line's overrides applied.
SceneDesc sceneOf(const BakeCommand& c) {
    // Parsing checks the receivers, which loads a lightmap's meshes: a large OBJ's load shows as
    // its own phase ([load mesh.obj]), as it does for convert.
    SceneDesc scene = [&] {
        OpeningProgress opening(c.quiet);
        return loadScene(c.scenePath);
    }();
    if (c.outputOption->count()) {
        requireOutputFolder("--output", c.output);
        scene.output = c.output, scene.outputFromScene = false;
    }
    disableOptimizations(scene.options, c.disabled);
    if (!c.simd.empty()) scene.options.simd = parseSimdLevel(c.simd, "--simd");
    if (!c.sampleTable.empty()) scene.options.sampleTable = c.sampleTable == "on";
    if (!c.closedCasters.empty()) scene.options.closedCasters = c.closedCasters == "on";
    if (!c.embreeFilter.empty()) scene.options.embreeRuleFilter = c.embreeFilter == "on";
    // Out of range is an input error (exit 1), as for every option of the right form; NaN too.
    if (c.mapResolutionOption->count()) {
        requireInRange("--penumbra-map-resolution", c.mapResolution, 16, 16384);
        scene.bakeOptions["penumbra_map_resolution"] = c.mapResolution;
    }
    if (c.mapBiasOption->count()) {
        requireInRange("--penumbra-map-bias", c.mapBias, 0.0, 1e6);
        scene.bakeOptions["penumbra_map_bias"] = c.mapBias;
    }
    if (!c.mapLookup.empty()) scene.bakeOptions["penumbra_map_lookup"] = c.mapLookup;
    if (c.mapTapsOption->count()) {
        requireInRange("--penumbra-map-taps", c.mapTaps, 1, 8);
        scene.bakeOptions["penumbra_map_taps"] = c.mapTaps;
    }
    return scene;
}

BakeSettings settingsOf(const BakeCommand& c) {
    BakeSettings settings;
    settings.method = casterEntry(c.method).name;
    if (c.threads < 0 || c.threads > kMaxThreads)
        throw InputError(fmt::format("--threads: must be in 0..{} (0: all cores), got {}", kMaxThreads, c.threads));
    settings.threads = c.threads;
    settings.statsPath = c.statsPath;
    settings.dumpDir = c.dumpDir;
    settings.visibilityPath = c.visibilityPath;
    settings.quiet = c.quiet;
    if (c.budgetOption->count()) {
        settings.memoryBudget = parseMemoryBudget(c.memoryBudget);
    }
    settings.tmpDir = c.tmpDir;
    settings.keepBuckets = c.keepBuckets;
    settings.shard = shardSettings(c.shard);
    return settings;
}

}  // namespace

uint64_t parseMemoryBudget(const std::string& text) {
    const uint64_t bytes = parseByteSize(text, "--memory-budget");
    if (bytes == 0) throw InputError("--memory-budget: must be more than 0 (leave it out for no budget)");
    return bytes;
}

CLI::App* addBakeCommand(CLI::App& app, BakeCommand& c) {
    CLI::App* bake = app.add_subcommand("bake", "bake soft shadows for a scene file");
    bake->add_option("scene", c.scenePath, "scene file (JSON)")->required();
    c.outputOption = bake->add_option("-o,--output", c.output, "output file (overrides the scene's \"output\")");
    std::string methods;
    for (const std::string& name : casterNames()) methods += (methods.empty() ? "" : ", ") + name;
    bake->add_option("--method", c.method, "shadow method: " + methods + " (default hpc)");
    bake->add_option("--threads", c.threads, "worker threads (default: all cores)");
    c.statsOption = bake->add_option("--stats", c.statsPath, "write JSON stats to this file");
    c.dumpOption =
        bake->add_option("--dump", c.dumpDir, "write receivers.npy, samples.npy, masks.npy and rule.json to this directory");
    bake->add_option("--visibility", c.visibilityPath, "write every receiver's visible fraction as a float32 .npy");
    bake->add_flag("-q,--quiet", c.quiet, "no progress on stderr");
    addCastOptions(*bake, c);
    c.budgetOption =
        bake->add_option("--memory-budget", c.memoryBudget, "bound on bake memory, e.g. 256M or 2G; receivers are tiled to fit")
            ->check(byteSizeForm());
    c.tmpOption = bake->add_option("--tmp", c.tmpDir, "directory for temporary bucket files (default: the system temp dir)");
    bake->add_flag("--keep-buckets", c.keepBuckets, "keep the bucket files (for debugging)");
    addShardOptions(*bake, c.shard);
    return bake;
}

/// Warns of the options of another method than the bake's, which it ignores: `--embree-filter
/// off` with hpc was taken without a word (sweep M at stop 63).
void warnOtherMethodsOptions(const BakeCommand& c, const std::string& method) {
    if (!c.embreeFilter.empty() && method != "embree")
        printWarning("--embree-filter applies to --method embree only; --method {} ignores it", method);
    if (method == "penumbra-map") return;
    const std::pair<const char*, bool> mapOptions[] = {{"--penumbra-map-resolution", c.mapResolutionOption->count() > 0},
                                                        {"--penumbra-map-bias", c.mapBiasOption->count() > 0},
                                                        {"--penumbra-map-lookup", !c.mapLookup.empty()},
                                                        {"--penumbra-map-taps", c.mapTapsOption->count() > 0}};
    for (const auto& [option, given] : mapOptions)
        if (given) printWarning("{} applies to --method penumbra-map only; --method {} ignores it", option, method);
}

void runBakeCommand(const BakeCommand& c) {
    for (auto [option, value] : {std::pair{c.outputOption, &c.output}, {c.statsOption, &c.statsPath},
                                 {c.dumpOption, &c.dumpDir}, {c.tmpOption, &c.tmpDir}, {c.budgetOption, &c.memoryBudget}})
        requireNonEmpty(option, *value);
    const SceneDesc scene = sceneOf(c);
    const BakeSettings settings = settingsOf(c);
    warnOtherMethodsOptions(c, settings.method);
    nlohmann::json stats = runBake(scene, settings);
    if (c.quiet) return;
    fmt::print(stderr, "penumbra: {} receivers, {} samples, {} triangles, {:.2f} s -> {}\n", stats["receivers"].get<uint64_t>(),
               stats["light_samples"].get<int>(), stats["counters"]["triangles_read"].get<uint64_t>(),
               stats["table2"]["total_time_s"].get<double>(), writtenFiles(stats));
}

}  // namespace penumbra
