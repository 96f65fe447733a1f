#include "bake/Pipeline.h"

#include "bake/BakeDump.h"
#include "bake/ClosedSolids.h"
#include "bake/EmbreeCaster.h"
#include "bake/HeckbertHerf.h"
#include "bake/MemoryPlan.h"
#include "bake/PenumbraCaster.h"
#include "bake/PenumbraMap.h"
#include "bake/ReceiverKind.h"
#include "bake/ReceiverShading.h"
#include "bake/ReferenceCaster.h"
#include "bake/SampleMaskTable.h"
#include "bake/SsvCaster.h"
#include "bake/SsvScene.h"
#include "bake/SunLight.h"
#include "bucket/BucketPlan.h"
#include "stream/AtomicFile.h"
#include "stream/Error.h"
#include "stream/Memory.h"
#include "stream/Npy.h"
#include "stream/PrefetchSource.h"
#include "stream/Progress.h"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/info.h>

#include <filesystem>

namespace penumbra {
namespace {

/// Everything the casting stage needs, gathered by the streaming pass.
struct Prepared {
    std::vector<LightDesc> lights;  ///< the scene's lights
    LightSamples samples;
    CastOptions options;            ///< the scene's, with the rule's epsilon length L set
    OpenedSolids openedSolids;      ///< closed solids a light reaches inside: cast as open
    ReceiverSet receivers;
    std::vector<uint32_t> sampleSets;
    TriangleSourcePtr blockers;           ///< replayable, largest first when sorting is on
    BucketReplaySource* replay = nullptr; ///< inside `blockers` when bucketed, for I/O counters
    uint64_t triangleCount = 0;
    uint64_t bucketBufferBytes = 0;
};

/// Rejects NaN/inf vertices as they stream by, naming the triangle's position in the stream, and
/// grows the scene's bounding box.
class FiniteCheck {
public:
    explicit FiniteCheck(const SceneDesc& scene) : scene_(scene) {}
    void operator()(std::span<const Triangle> chunk) {
        for (size_t i = 0; i < chunk.size(); ++i) {
            if (!isFinite(chunk[i]))
                fail(scene_.file, "geometry triangle {} has a non-finite (NaN or infinite) vertex", seen_ + i);
            for (const glm::vec3& v : chunk[i].v) lo_ = glm::min(lo_, v), hi_ = glm::max(hi_, v);
        }
        seen_ += chunk.size();
    }
    SceneBox box() const {
        SceneBox b;
        if (seen_) b.add(glm::dvec3(lo_)), b.add(glm::dvec3(hi_));
        return b;
    }

private:
    const SceneDesc& scene_;
    uint64_t seen_ = 0;
    glm::vec3 lo_{INFINITY}, hi_{-INFINITY};
};

/// L of the rule's receiver epsilon (BlockingRule.h): the largest |coordinate| of any receiver,
/// else of any triangle (a bake whose receivers all sit at the origin), else 1.
double epsilonLength(const ReceiverSet& receivers, const SceneBox& geometry) {
    double length = 0.0;
    for (const glm::vec3& r : receivers.position)
        length = std::max({length, double(std::abs(r.x)), double(std::abs(r.y)), double(std::abs(r.z))});
    if (length > 0.0) return length;
    if (!geometry.empty())
        for (const glm::dvec3& c : {geometry.lo, geometry.hi})
            length = std::max({length, std::abs(c.x), std::abs(c.y), std::abs(c.z)});
    return length > 0.0 ? length : 1.0;
}

/// One line per light that reaches inside closed solids: their triangles are cast as open
/// surfaces, which keeps every shadow (bake/ClosedSolids.h).
void reportOpenedSolids(const OpenedSolids& opened, const std::vector<LightDesc>& lights, bool quiet) {
    if (quiet) return;
    for (size_t l = 0; l < opened.perLight.size(); ++l)
        if (opened.perLight[l])
            printNote("{} reaches inside {} closed solid(s); their triangles are cast as open surfaces",
                      lights[l].where, opened.perLight[l]);
}

/// Pass 1 over the stream: camera receivers are rasterized (or points loaded) while the area
/// histogram is built and every vertex is checked. Pass 2 streams the blockers into area buckets
/// on disk; casting then replays the buckets, largest first, once per memory tile. So the source
/// is read at most twice and no pass holds more than a bounded window of triangles.
Prepared prepare(const SceneDesc& scene, const BakeSettings& settings, ReceiverKind& kind, double& streamSeconds,
                 BucketStats& buckets) {
    Prepared p;
    p.lights = scene.lights;
    p.samples = generateLightSamples(p.lights, scene.options.groupSize, scene.seed);
    p.options = scene.options;
    // Read ahead on a thread of its own, so parsing or generation overlaps with rasterizing
    // receivers (scan pass) and writing bucket files (bucket pass).
    TriangleSourcePtr source = std::make_unique<PrefetchSource>(openSceneGeometry(scene));
    AreaHistogram histogram;
    {
        ScopedTimer timer(streamSeconds);
        ProgressReporter progress("scan", source->sizeHint().value_or(0), settings.quiet);
        FiniteCheck check(scene);
        ClosedSolidScan solids(p.samples);
        std::vector<Triangle> chunk(kTriangleChunk);
        while (size_t n = source->read(chunk)) {
            std::span<const Triangle> part(chunk.data(), n);
            check(part);
            histogram.add(part);
            kind.scan(part);
            if (scene.options.closedCasters) solids.scan(part);
            progress.update(n);
        }
        p.receivers = kind.receivers();
        progress.done();
        p.openedSolids = solids.finish();
        p.options.epsilonLength = epsilonLength(p.receivers, check.box());
    }
    reportOpenedSolids(p.openedSolids, p.lights, settings.quiet);
    returnFreedMemory();  // the z-buffer is gone; keep it from inflating the casting phase's RSS
    p.sampleSets.resize(p.receivers.size());
    for (size_t i = 0; i < p.receivers.size(); ++i) p.sampleSets[i] = uint32_t(sampleSetOf(i, p.samples.sets, scene.seed));
    p.triangleCount = histogram.count();

    source->rewind();
    if (!p.openedSolids.ordinals.empty())
        source = std::make_unique<OpenSolidsSource>(std::move(source), p.openedSolids.ordinals);
    // Methods that stream the blockers in any order have no use for the area buckets.
    if (!scene.options.sortBlockers || settings.method == Method::PenumbraMap || settings.method == Method::Hh) {  // stream order: replay the source itself
        if (kind.wantsRescan()) {  // no bucket pass to ride along with: a read of its own
            std::vector<Triangle> chunk(kTriangleChunk);
            while (size_t n = source->read(chunk)) kind.rescan(std::span<const Triangle>(chunk.data(), n));
            source->rewind();
        }
        p.blockers = std::move(source);  // already read ahead
        return p;
    }
    BucketOptions options;
    options.tmpDir = settings.tmpDir;
    options.keep = settings.keepBuckets;
    ProgressReporter progress("bucket", p.triangleCount, settings.quiet);
    // A receiver kind that wants a second look at the geometry (smooth shading) gets it during
    // the bucket pass, so the source is still read only twice.
    const bool rescan = kind.wantsRescan();
    auto set = std::make_shared<BucketSet>(writeBuckets(*source, planBucketRanges(options, &histogram), options, &buckets,
                                                        [&](std::span<const Triangle> c) {
                                                            if (rescan) kind.rescan(c);
                                                            progress.update(c.size());
                                                        }));
    progress.done();
    auto replay = std::make_unique<BucketReplaySource>(set, options.readBufferBytes);
    p.replay = replay.get();
    p.bucketBufferBytes = options.writeMemoryBytes() + options.readBufferBytes;
    p.blockers = std::make_unique<PrefetchSource>(std::move(replay));
    return p;
}

/// Adds the stats of one more tile or cast pass to @p total; they run one after another, so
/// peaks are the largest one's, not the sum.
void accumulate(CastStats& total, const CastStats& s) {
    total.hierarchyBuildSeconds += s.hierarchyBuildSeconds;
    total.castSeconds += s.castSeconds;
    total.replayReadSeconds += s.replayReadSeconds;
    total.trianglesProcessed += s.trianglesProcessed;
    total.trianglesCulledAtRoot += s.trianglesCulledAtRoot;
    total.closedBackFaces += s.closedBackFaces;
    total.rebuilds += s.rebuilds;
    total.hardShadowTests += s.hardShadowTests;
    total.tableDecidedRelations += s.tableDecidedRelations;
    total.sampleTableBytes = std::max(total.sampleTableBytes, s.sampleTableBytes);
    // Tiles run one after another: peaks are the largest tile's, not the sum.
    total.peakLiveMasks = std::max(total.peakLiveMasks, s.peakLiveMasks);
    total.peakMaskBytes = std::max(total.peakMaskBytes, s.peakMaskBytes);
    total.peakHierarchyBytes = std::max(total.peakHierarchyBytes, s.peakHierarchyBytes);
    total.receiverBytes = std::max(total.receiverBytes, s.receiverBytes);
}

/// Within a memory tile, threads work on disjoint sub-tiles, four per thread: more sub-tiles even
/// out uneven work (measured on GRIDS with a barrier per chunk, 2 threads: 2 per thread cast in
/// 4.28 s, 4 in 3.86 s, 8 in 3.92 s; docs/performance.md, "Parallelism").
int subTiles(int threads) { return threads > 1 ? 4 * threads : 1; }

/// Hierarchical penumbra casting of receivers [first, end), one memory tile after another; each
/// tile replays the blockers. The first tile of the bake's first pass reads the replay the scan
/// pass left ready; every other tile rewinds it. The kind sees the first tile's chunks when it
/// asks for them.
CastStats castHierarchical(Prepared& p, const SceneDesc& scene, const BakeSettings& settings, int threads,
                           const MemoryPlan& plan, const ReceiverShader& shader, ReceiverResults& results,
                           VisibilityMasks* dumpMasks, ReceiverKind& kind, uint32_t first, bool rewindFirst) {
    CastStats total;
    std::vector<uint32_t> ids(p.receivers.size() - first);
    for (uint32_t i = 0; i < ids.size(); ++i) ids[i] = first + i;
    const auto tiles = partitionReceivers(p.receivers, ids, plan.tiles);
    ProgressReporter progress("cast", p.triangleCount * tiles.size(), settings.quiet);
    const bool feedKind = kind.wantsCastChunks();
    std::vector<Triangle> chunk(kTriangleChunk);
    for (size_t t = 0; t < tiles.size(); ++t) {
        const auto& tile = tiles[t];
        double readSeconds = 0;
        PenumbraCaster caster(p.samples, p.receivers, p.sampleSets, p.options, subTiles(threads), tile);
        if (t > 0 || rewindFirst) p.blockers->rewind();
        for (;;) {
            size_t n;
            {
                ScopedTimer timer(readSeconds);
                n = p.blockers->read(chunk);
            }
            if (n == 0) break;
            std::span<const Triangle> part(chunk.data(), n);
            // Smooth shading's pass over the faces runs on this thread while the tiles cast earlier
            // chunks on the others. (As a parallel_invoke beside cast() it could sit unstolen in
            // this thread's queue while cast() waited for a ring slot.)
            if (feedKind && t == 0) kind.castChunk(part);
            caster.cast(part);
            progress.update(n);
        }
        caster.finish([&](uint32_t r, const uint64_t* words, bool full) {
            shader.shade(r, words, full, results);
            if (dumpMasks)
                for (int k = 0; k < dumpMasks->groups; ++k)
                    dumpMasks->row(r)[k] = full ? p.samples.groups[k].fullMask() : (words ? words[k] : 0);
        });
        // Tile hierarchies are built on worker threads, in their malloc arenas; hand the freed
        // memory back before the next tile, or arenas keep it and RSS creeps past the plan.
        returnFreedMemory();
        CastStats s = caster.stats();
        s.replayReadSeconds = readSeconds;
        accumulate(total, s);
    }
    progress.done();
    return total;
}

/// Calls @p shade for receivers [first, end) on the worker threads; each writes only its own row.
template <class F>
void shadeInParallel(uint32_t first, uint32_t end, F&& shade) {
    tbb::parallel_for(tbb::blocked_range<uint32_t>(first, end, 1024), [&](const tbb::blocked_range<uint32_t>& range) {
        for (uint32_t r = range.begin(); r != range.end(); ++r) shade(r);
    });
}

/// Calls @p f with @p all in chunks of kTriangleChunk.
template <class F>
void forEachChunk(const std::vector<Triangle>& all, F&& f) {
    for (size_t i = 0; i < all.size(); i += kTriangleChunk)
        f(std::span<const Triangle>(all).subspan(i, std::min(kTriangleChunk, all.size() - i)));
}

/// Receivers [first, end) of @p set as a set of their own (the ray casters take whole sets).
ReceiverSet tailOf(const ReceiverSet& set, size_t first) {
    ReceiverSet out;
    out.position.assign(set.position.begin() + first, set.position.end());
    out.normal.assign(set.normal.begin() + first, set.normal.end());
    return out;
}

/// Appends @p extra (refinement receivers) to @p set.
void append(ReceiverSet& set, const ReceiverSet& extra) {
    set.position.insert(set.position.end(), extra.position.begin(), extra.position.end());
    set.normal.insert(set.normal.end(), extra.normal.begin(), extra.normal.end());
    set.pixel.insert(set.pixel.end(), extra.pixel.begin(), extra.pixel.end());
    set.depth.insert(set.depth.end(), extra.depth.begin(), extra.depth.end());
}

/// The counters of the methods other than hpc, for the stats JSON.
struct MethodStats {
    EmbreeStats embree;
    SsvStats ssv;
    PenumbraMapStats penumbraMap;
    HeckbertHerfStats hh;
};

/// Every method but hpc, for receivers [first, end): the streamed ones (penumbra-map, hh) read
/// the blockers themselves; the ray casters get the whole scene, read into @p all once.
void castOtherMethod(Prepared& p, const SceneDesc& scene, const BakeSettings& settings, ReceiverKind& kind,
                     const ReceiverShader& shader, uint32_t first, std::vector<Triangle>& all, VisibilityMasks& masks,
                     ReceiverResults& results, MethodStats& stats) {
    const ReceiverSet part = first == 0 ? ReceiverSet{} : tailOf(p.receivers, first);
    const ReceiverSet& targets = first == 0 ? p.receivers : part;
    const std::span<const uint32_t> sets = std::span<const uint32_t>(p.sampleSets).subspan(first);
    const uint64_t work = settings.method == Method::PenumbraMap ? 2 * p.triangleCount * uint64_t(p.samples.lightCount())
                          : settings.method == Method::Hh     ? p.triangleCount
                                                              : targets.size();
    ProgressReporter progress(methodName(settings.method), work, settings.quiet);
    auto tick = [&](uint64_t n) { progress.update(n); };
    const ReceiverEpsilon eps = receiverEpsilonOf(p.options);
    if (settings.method == Method::PenumbraMap) {  // streams the blockers, in stream order
        if (kind.wantsCastChunks()) {
            p.blockers->rewind();
            std::vector<Triangle> chunk(kTriangleChunk);
            while (size_t n = p.blockers->read(chunk)) kind.castChunk(std::span<const Triangle>(chunk.data(), n));
        }
        const std::vector<float> v = castPenumbraMap(p.samples, targets, sets, *p.blockers, eps, scene.penumbraMap, &stats.penumbraMap, tick);
        progress.done();
        shadeInParallel(first, uint32_t(p.receivers.size()), [&](uint32_t r) {
            shader.shadeVisibleFraction(r, &v[size_t(r - first) * p.samples.lightCount()], results);
        });
        return;
    }
    if (settings.method == Method::Hh) {  // streams the blockers once; lightmaps are never refined
        VisibilityMasks m = castHeckbertHerf(p.samples, targets, sets, *p.blockers, eps, *kind.receiverPolygons(), &stats.hh, tick);
        progress.done();
        std::copy(m.words.begin(), m.words.end(), masks.words.begin());
        shadeInParallel(0, uint32_t(p.receivers.size()), [&](uint32_t r) { shader.shade(r, masks.row(r), false, results); });
        return;
    }
    // The ray casters need the whole scene in memory: that is their nature, not ours.
    if (all.empty()) {
        all = readAll(*p.blockers);
    }
    if (kind.wantsCastChunks()) forEachChunk(all, [&](std::span<const Triangle> c) { kind.castChunk(c); });
    VisibilityMasks m = settings.method == Method::Reference ? castReference(p.samples, targets, sets, all, eps, tick)
                        : settings.method == Method::Ssv
                            ? castSsv(p.samples, targets, sets, all, eps, SsvOptions{}, &stats.ssv, tick)
                            : castEmbree(p.samples, targets, sets, all, eps, &stats.embree, tick, p.options.embreeRuleFilter);
    progress.done();
    std::copy(m.words.begin(), m.words.end(), masks.words.begin() + size_t(first) * masks.groups);
    shadeInParallel(first, uint32_t(p.receivers.size()), [&](uint32_t r) { shader.shade(r, masks.row(r), false, results); });
}

/// The stats JSON's section of the method, if it has one.
void addMethodStats(nlohmann::json& out, Method method, const MethodStats& s, const SceneDesc& scene) {
    if (method == Method::Embree)
        out["embree"] = {{"build_time_s", s.embree.buildSeconds}, {"trace_time_s", s.embree.traceSeconds},
                         {"rays", s.embree.rays}, {"scene_bytes", s.embree.sceneBytes},
                         {"filter_calls", s.embree.filterCalls}, {"filter_exact", s.embree.filterExact},
                         {"filter_rejected", s.embree.filterRejected}};
    if (method == Method::Ssv) out["ssv"] = ssvStatsJson(s.ssv);
    if (method == Method::Hh) out["hh"] = heckbertHerfStatsJson(s.hh);
    if (method == Method::PenumbraMap) out["penumbra_map"] = penumbraMapStatsJson(s.penumbraMap, scene.penumbraMap);
}

}  // namespace

Method parseMethod(const std::string& name) {
    if (name == "hpc") return Method::Hpc;
    if (name == "reference") return Method::Reference;
    if (name == "embree") return Method::Embree;
    if (name == "ssv") return Method::Ssv;
    if (name == "penumbra-map") return Method::PenumbraMap;
    if (name == "hh") return Method::Hh;
    throw InputError("--method: unknown method \"" + name + "\" (known: hpc, reference, embree, ssv, penumbra-map, hh)");
}

const char* methodName(Method m) {
    switch (m) {
        case Method::Hpc: return "hpc";
        case Method::Reference: return "reference";
        case Method::Embree: return "embree";
        case Method::Ssv: return "ssv";
        case Method::PenumbraMap: return "penumbra-map";
        case Method::Hh: return "hh";
    }
    return "?";
}

nlohmann::json runBake(const SceneDesc& scene, const BakeSettings& settings) {
    Stopwatch total;
    const int threads = settings.threads > 0 ? settings.threads : int(tbb::info::default_concurrency());
    tbb::global_control parallelism(tbb::global_control::max_allowed_parallelism, size_t(threads));
    const bool dump = !settings.dumpDir.empty();

    // Check before any work that the scan pass fits; the receiver count is known after it, and
    // the full plan is checked again then, before casting.
    std::unique_ptr<ReceiverKind> kind = makeReceiverKind(scene.receivers, scene);
    if (settings.method == Method::Hh && !kind->receiverPolygons())
        throw InputError(fmt::format("--method hh: applies to lightmap receivers only (this scene's receivers are \"{}\")",
                                     scene.receivers.value("type", std::string("?"))));
    MemoryDemand demand;
    demand.scanBytes = kind->scanBytes();
    int samplesTotal = 0;
    for (const LightDesc& l : scene.lights) samplesTotal += l.samples;
    demand.groups = (samplesTotal + scene.options.groupSize - 1) / scene.options.groupSize;
    demand.umbraWords = (demand.groups + 63) / 64;
    demand.dumpMasks = dump;
    planMemory(demand, settings.memoryBudget);

    double streamSeconds = 0;
    BucketStats buckets;
    Prepared p = prepare(scene, settings, *kind, streamSeconds, buckets);
    demand.receivers = p.receivers.size();
    demand.outputBytes = kind->outputBytes(p.receivers.size());
    demand.groups = p.samples.groupCount();
    demand.umbraWords = (demand.groups + 63) / 64;
    demand.sampleBytes = p.samples.positions.size() * sizeof(glm::vec3);
    if (scene.options.sampleTable)  // one copy per caster; casters (memory tiles) run one at a time
        for (uint32_t l = 0; l < uint32_t(p.samples.lightCount()); ++l)
            demand.sampleBytes += SampleMaskTable::plannedBytes(p.samples, l, scene.options.sampleTableAngles,
                                                                scene.options.sampleTableOffsets);
    // Bucket buffers, the prefetch queue and the caster's ring of prepared chunks are fixed buffers.
    demand.bufferBytes = p.bucketBufferBytes + 8 * kTriangleChunk * sizeof(Triangle) +
                         PenumbraCaster::kMaxRingChunks * PenumbraCaster::preparedChunkBytes(scene.lights.size());
    demand.kindBytes = kind->residentBytes();
    if (settings.method == Method::Ssv) demand.sceneBytes = SsvScene::plannedBytes(p.triangleCount, p.samples.lightCount());
    if (settings.method == Method::PenumbraMap) demand.sceneBytes = scene.penumbraMap.mapBytes();
    MemoryPlan plan = planMemory(demand, settings.memoryBudget);

    ReceiverResults results;
    results.resize(p.receivers.size(), int(p.lights.size()));
    VisibilityMasks masks;
    if (dump && settings.method == Method::PenumbraMap)
        throw InputError("--dump: penumbra-map gives each receiver a visible fraction, not per-sample masks (use --visibility)");
    if (dump || (settings.method != Method::Hpc && settings.method != Method::PenumbraMap)) masks = VisibilityMasks(p.receivers.size(), p.samples.groupCount());

    CastStats cast;
    MethodStats methodStats;
    double castSeconds = 0, refineSeconds = 0;
    std::vector<Triangle> all;  // the ray casters' whole scene, read once
    // One cast of receivers [first, end): the first pass casts them all, a refinement pass only
    // the receivers it added.
    auto castPass = [&](uint32_t first, bool rewind) {
        ScopedTimer timer(castSeconds);
        ReceiverShader shader(p.lights, p.samples, p.receivers, p.sampleSets);
        if (settings.method == Method::Hpc) {
            accumulate(cast, castHierarchical(p, scene, settings, threads, plan, shader, results, dump ? &masks : nullptr,
                                              *kind, first, rewind));
            return;
        }
        castOtherMethod(p, scene, settings, *kind, shader, first, all, masks, results, methodStats);
    };
    castPass(0, false);

    // Adaptive refinement: the kind looks at the first pass, finds its new receivers in one more
    // read of the blockers, and only those are cast.
    const size_t firstPass = p.receivers.size();
    if (kind->refine(p.receivers, results)) {
        demand.kindBytes = kind->residentBytes() + kind->refineBytes();
        // The refinement's rasterizer fits, or a clear error; the stats report the largest minimum.
        const uint64_t refineMinimum = planMemory(demand, settings.memoryBudget).minimumBudget;
        {
            ScopedTimer timer(refineSeconds);
            if (all.empty()) {  // hpc and the streamed methods read the blockers again
                p.blockers->rewind();
                std::vector<Triangle> chunk(kTriangleChunk);
                while (size_t n = p.blockers->read(chunk)) kind->refineScan(std::span<const Triangle>(chunk.data(), n));
            } else {
                forEachChunk(all, [&](std::span<const Triangle> c) { kind->refineScan(c); });
            }
            append(p.receivers, kind->refinedReceivers());
        }
        returnFreedMemory();
        for (size_t i = firstPass; i < p.receivers.size(); ++i)
            p.sampleSets.push_back(uint32_t(sampleSetOf(i, p.samples.sets, scene.seed)));
        results.extend(p.receivers.size());
        if (masks.groups) masks.words.resize(p.receivers.size() * size_t(masks.groups), 0);
        demand.receivers = p.receivers.size();
        demand.kindBytes = kind->residentBytes();
        demand.outputBytes = kind->outputBytes(p.receivers.size());
        plan = planMemory(demand, settings.memoryBudget);
        plan.minimumBudget = std::max(plan.minimumBudget, refineMinimum);
        castPass(uint32_t(firstPass), true);
    }

    kind->write(OutputContext{scene, p.receivers, p.samples, results, scene.output, firstPass});
    if (!settings.visibilityPath.empty()) {
        const uint64_t shape[1] = {p.receivers.size()};
        ensureParentDirectory(settings.visibilityPath);
        writeNpy(settings.visibilityPath, "<f4", shape, results.visibility.data(), results.visibility.size() * sizeof(float));
    }
    if (dump) writeBakeDump(settings.dumpDir, p.receivers, p.sampleSets, p.samples, masks, receiverEpsilonOf(p.options));

    uint64_t blocked = 0;
    for (float v : results.visibility) blocked += uint64_t(std::llround((1.0 - v) * p.samples.sampleCount));
    nlohmann::json stats = {
        {"scene", scene.file},
        {"method", methodName(settings.method)},
        {"threads", threads},
        {"simd", simdName(hardShadowKernels(scene.options.simd).level)},
        {"receivers", p.receivers.size()},
        {"light_samples", p.samples.sampleCount},
        {"sample_sets", p.samples.sets},
        {"light_sample_groups", p.samples.groupCount()},
        {"epsilon", {{"relative", p.options.epsilon}, {"length", p.options.epsilonLength}}},
        {"blocked_relations", blocked},
        {"table2",
         {{"sort_time_s", buckets.seconds},
          {"hierarchy_build_time_s", cast.hierarchyBuildSeconds},
          {"penumbra_cast_time_s", settings.method == Method::Hpc ? cast.castSeconds : castSeconds},
          {"replay_read_time_s", cast.replayReadSeconds},
          {"samples_memory_bytes", p.receivers.bytes() + cast.receiverBytes},
          {"peak_hierarchy_memory_bytes", cast.peakHierarchyBytes},
          {"peak_mask_memory_bytes", cast.peakMaskBytes},
          {"total_time_s", total.seconds()}}},
        {"counters",
         {{"triangles_read", p.triangleCount},
          {"triangles_culled_at_root", cast.trianglesCulledAtRoot},
          {"closed_back_faces_skipped", cast.closedBackFaces},
          {"closed_solids_opened", p.openedSolids.ordinals.size()},
          {"closed_triangles_opened", p.openedSolids.triangles},
          {"rebuilds", cast.rebuilds},
          {"peak_live_masks", cast.peakLiveMasks},
          {"hard_shadow_tests", cast.hardShadowTests},
          {"table_decided_relations", cast.tableDecidedRelations},
          {"sample_table_bytes", cast.sampleTableBytes},
          {"peak_rss_bytes", peakRssBytes()}}},
        {"memory_plan",
         {{"budget_bytes", plan.budget},
          {"tiles", plan.tiles},
          {"resident_bytes", plan.residentBytes},
          {"per_receiver_bytes", plan.perReceiverBytes},
          {"minimum_budget_bytes", plan.minimumBudget}}},
        {"stream", {{"scan_time_s", streamSeconds}, {"triangles", p.triangleCount}}},
        {"buckets",
         {{"files", buckets.nonEmptyFiles},
          {"bytes_written", buckets.bytesWritten},
          {"bytes_read", p.replay ? p.replay->bytesRead() : 0},
          {"bytes_per_triangle", buckets.bytesPerTriangle()},
          {"write_mb_per_s", buckets.megabytesPerSecond()},
          {"read_mb_per_s", p.replay && p.replay->readSeconds() > 0 ? double(p.replay->bytesRead()) / 1e6 / p.replay->readSeconds() : 0.0},
          {"pass_time_s", buckets.seconds}}},
    };
    if (nlohmann::json extra = kind->stats(); extra.is_object())
        for (auto& [key, value] : extra.items()) stats[key] = value;
    if (refineSeconds > 0) stats["antialias"]["refine_scan_time_s"] = refineSeconds;
    addMethodStats(stats, settings.method, methodStats, scene);
    if (!settings.statsPath.empty()) {
        std::string text = stats.dump(2) + "\n";
        ensureParentDirectory(settings.statsPath);
        writeFileAtomically(settings.statsPath, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
    }
    return stats;
}

}  // namespace penumbra
