#include "bake/Pipeline.h"

#include "bake/EmbreeCaster.h"
#include "bake/ImageWriters.h"
#include "bake/PenumbraCaster.h"
#include "bake/ReferenceCaster.h"
#include "receivers/PointReceivers.h"
#include "bake/CameraOutput.h"
#include "bucket/AreaSort.h"
#include "stream/AtomicFile.h"
#include "stream/Error.h"
#include "stream/Memory.h"
#include "stream/Npy.h"
#include "stream/Progress.h"

#include <tbb/global_control.h>
#include <tbb/info.h>

#include <filesystem>

namespace penumbra {
namespace {

/// Everything the casting stage needs, gathered by the streaming pass(es).
struct Prepared {
    LightSamples samples;
    ReceiverSet receivers;
    std::vector<uint32_t> sampleSets;
    std::vector<Triangle> triangles;  // in memory for now; bucket files replace this out of core
};

void checkFinite(std::span<const Triangle> chunk, uint64_t firstIndex, const SceneDesc& scene) {
    for (size_t i = 0; i < chunk.size(); ++i)
        if (!isFinite(chunk[i]))
            fail(scene.file, "geometry triangle {} has a non-finite (NaN or infinite) vertex", firstIndex + i);
}

void writeDump(const std::string& dir, const Prepared& p, const VisibilityMasks& masks) {
    std::filesystem::path base(dir);
    std::error_code ec;
    std::filesystem::create_directories(base, ec);
    if (ec) fail(dir, "cannot create dump directory: {}", ec.message());
    const uint64_t n = p.receivers.size(), k = uint64_t(p.samples.sampleCount);
    std::vector<float> rec(n * 7);
    for (size_t i = 0; i < n; ++i) {
        const glm::vec3 &x = p.receivers.position[i], &nn = p.receivers.normal[i];
        float row[7] = {x.x, x.y, x.z, nn.x, nn.y, nn.z, float(p.sampleSets[i])};
        std::copy(row, row + 7, rec.begin() + i * 7);
    }
    uint64_t recShape[2] = {n, 7};
    writeNpy((base / "receivers.npy").string(), "<f4", recShape, rec.data(), rec.size() * sizeof(float));
    uint64_t sampleShape[3] = {uint64_t(p.samples.sets), k, 3};
    writeNpy((base / "samples.npy").string(), "<f4", sampleShape, p.samples.positions.data(),
             p.samples.positions.size() * sizeof(glm::vec3));
    std::vector<uint64_t> dense = masks.toDumpLayout(p.samples);
    uint64_t maskShape[2] = {n, (k + 63) / 64};
    writeNpy((base / "masks.npy").string(), "<u8", maskShape, dense.data(), dense.size() * sizeof(uint64_t));
}

}  // namespace

Method parseMethod(const std::string& name) {
    if (name == "hpc") return Method::Hpc;
    if (name == "reference") return Method::Reference;
    if (name == "embree") return Method::Embree;
    throw InputError("--method: unknown method \"" + name + "\" (known: hpc, reference, embree)");
}

const char* methodName(Method m) {
    switch (m) {
        case Method::Hpc: return "hpc";
        case Method::Reference: return "reference";
        case Method::Embree: return "embree";
    }
    return "?";
}

nlohmann::json runBake(const SceneDesc& scene, const BakeSettings& settings) {
    Stopwatch total;
    const int threads = settings.threads > 0 ? settings.threads : int(tbb::info::default_concurrency());
    tbb::global_control parallelism(tbb::global_control::max_allowed_parallelism, size_t(threads));
    const CastOptions& options = scene.options;

    Prepared p;
    p.samples = generateLightSamples(scene.lights, options.groupSize, scene.seed);

    // Pass over the stream: rasterize camera receivers and keep the blockers.
    double streamSeconds = 0;
    {
        ScopedTimer timer(streamSeconds);
        TriangleSourcePtr source = openSceneGeometry(scene);
        uint64_t seen = 0;
        auto keep = [&](std::span<const Triangle> chunk) {
            checkFinite(chunk, seen, scene);
            seen += chunk.size();
            p.triangles.insert(p.triangles.end(), chunk.begin(), chunk.end());
        };
        if (scene.receivers.kind == ReceiverKind::Camera) {
            p.receivers = rasterizeCamera(*source, scene.receivers.camera, keep);
        } else {
            p.receivers = loadPointReceivers(scene.receivers.pointsPath);
            std::vector<Triangle> chunk(kTriangleChunk);
            while (size_t n = source->read(chunk)) keep(std::span<const Triangle>(chunk.data(), n));
        }
    }
    p.sampleSets.resize(p.receivers.size());
    for (size_t i = 0; i < p.receivers.size(); ++i) p.sampleSets[i] = uint32_t(sampleSetOf(i, p.samples.sets, scene.seed));

    double sortSeconds = 0;
    if (options.sortBlockers) {
        ScopedTimer timer(sortSeconds);
        sortByAreaDescending(p.triangles);
    }

    VisibilityMasks masks(p.receivers.size(), p.samples.groupCount());
    CastStats cast;
    EmbreeStats embree;
    double castSeconds = 0;
    {
        ScopedTimer timer(castSeconds);
        if (settings.method == Method::Hpc) {
            ProgressReporter progress("cast", p.triangles.size(), settings.quiet);
            PenumbraCaster caster(p.samples, p.receivers, p.sampleSets, options, threads > 1 ? 2 * threads : 1);
            for (size_t i = 0; i < p.triangles.size(); i += kTriangleChunk) {
                size_t n = std::min(kTriangleChunk, p.triangles.size() - i);
                caster.cast(std::span<const Triangle>(p.triangles.data() + i, n));
                progress.update(n);
            }
            progress.done();
            caster.finish([&](uint32_t r, const uint64_t* words, bool full) {
                uint64_t* row = masks.row(r);
                for (int k = 0; k < masks.groups; ++k)
                    row[k] = full ? p.samples.groups[k].fullMask() : (words ? words[k] : 0);
            });
            cast = caster.stats();
        } else {
            ProgressReporter progress(methodName(settings.method), p.receivers.size(), settings.quiet);
            auto tick = [&](uint64_t n) { progress.update(n); };
            if (settings.method == Method::Reference)
                masks = castReference(p.samples, p.receivers, p.sampleSets, p.triangles, options.epsilon, tick);
            else
                masks = castEmbree(p.samples, p.receivers, p.sampleSets, p.triangles, options.epsilon, &embree, tick);
            progress.done();
        }
    }

    // Outputs.
    std::vector<float> visibility(p.receivers.size());
    for (size_t i = 0; i < visibility.size(); ++i) visibility[i] = float(masks.visibleFraction(i, p.samples));
    if (scene.receivers.kind == ReceiverKind::Camera) {
        writeCameraOutputs(scene, p.receivers, p.samples, p.sampleSets, masks, visibility);
    } else {
        uint64_t shape[1] = {visibility.size()};
        ensureParentDirectory(scene.output);
        writeNpy(scene.output, "<f4", shape, visibility.data(), visibility.size() * sizeof(float));
    }
    if (!settings.dumpDir.empty()) writeDump(settings.dumpDir, p, masks);

    const uint64_t triangleBytes = p.triangles.size() * sizeof(Triangle);
    nlohmann::json stats = {
        {"scene", scene.file},
        {"method", methodName(settings.method)},
        {"threads", threads},
        {"receivers", p.receivers.size()},
        {"light_samples", p.samples.sampleCount},
        {"sample_sets", p.samples.sets},
        {"light_sample_groups", p.samples.groupCount()},
        {"blocked_relations", masks.blockedCount()},
        {"table2",
         {{"sort_time_s", sortSeconds},
          {"hierarchy_build_time_s", cast.hierarchyBuildSeconds},
          {"penumbra_cast_time_s", settings.method == Method::Hpc ? cast.castSeconds : castSeconds},
          {"samples_memory_bytes", p.receivers.bytes() + cast.receiverBytes},
          {"peak_hierarchy_memory_bytes", cast.peakHierarchyBytes},
          {"peak_mask_memory_bytes", cast.peakMaskBytes},
          {"total_time_s", total.seconds()}}},
        {"counters",
         {{"triangles_read", p.triangles.size()},
          {"triangles_culled_at_root", cast.trianglesCulledAtRoot},
          {"rebuilds", cast.rebuilds},
          {"peak_live_masks", cast.peakLiveMasks},
          {"hard_shadow_tests", cast.hardShadowTests},
          {"peak_rss_bytes", peakRssBytes()}}},
        {"stream", {{"time_s", streamSeconds}, {"triangle_bytes_in_memory", triangleBytes}}},
    };
    if (settings.method == Method::Embree)
        stats["embree"] = {{"build_time_s", embree.buildSeconds}, {"trace_time_s", embree.traceSeconds},
                           {"rays", embree.rays}, {"scene_bytes", embree.sceneBytes}};
    if (!settings.statsPath.empty()) {
        std::string text = stats.dump(2) + "\n";
        ensureParentDirectory(settings.statsPath);
        writeFileAtomically(settings.statsPath, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
    }
    return stats;
}

}  // namespace penumbra
