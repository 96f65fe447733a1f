#include "bake/Pipeline.h"

#include "bake/output/BakeDump.h"
#include "bake/BakeMemory.h"
#include "bake/BakeOutputs.h"
#include "bake/BakeStats.h"
#include "bake/MemoryPlan.h"
#include "bake/kinds/ReceiverKind.h"
#include "bake/shading/ReceiverShading.h"
#include "bake/WorkPlan.h"
#include "bake/cast/Caster.h"
#include "bake/cast/ClosedSolids.h"
#include "bake/cast/ReachCull.h"
#include "bake/cast/VisibilityMasks.h"
#include "bake/light/SunLight.h"
#include "bucket/BucketPlan.h"
#include "stream/AnonymousFile.h"
#include "stream/AtomicFile.h"
#include "stream/Error.h"
#include "stream/InputFile.h"
#include "stream/Memory.h"
#include "stream/PrefetchSource.h"
#include "stream/Progress.h"

#include <tbb/global_control.h>
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
Prepared prepare(const SceneDesc& scene, const BakeSettings& settings, ReceiverKind& kind, TriangleSourcePtr geometry,
                 const std::function<void(const Prepared&, uint64_t triangles)>& afterScan, double& streamSeconds,
                 BucketStats& buckets) {
    Prepared p;
    p.lights = scene.lights;
    p.samples = generateLightSamples(p.lights, scene.options.groupSize, scene.seed);
    p.options = scene.options;
    // Read ahead on a thread of its own, so parsing or generation overlaps with rasterizing
    // receivers (scan pass) and writing bucket files (bucket pass).
    TriangleSourcePtr source = std::make_unique<PrefetchSource>(std::move(geometry));
    // Before any triangle is read: the bucket files must fit on disk, and hours of work are announced.
    checkBucketDisk(settings.tmpDir, source->sizeHint(), scene.options.sortBlockers);
    noteLongBake(source->sizeHint().value_or(0), 1,
                 int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)), settings.quiet);
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
    afterScan(p, p.triangleCount);  // the exact memory check, before the bucket pass writes anything

    source->rewind();
    if (!p.openedSolids.ordinals.empty())
        source = std::make_unique<OpenSolidsSource>(std::move(source), p.openedSolids.ordinals);
    // A method that gains nothing from largest-first order (it holds or streams the scene in any
    // order) skips the bucket pass.
    if (!scene.options.sortBlockers || !casterEntry(settings.method).traits.sortedBlockers) {  // replay the source itself
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
    // What cannot block is never written: the reach culls, against every receiver, once the scan
    // has found them (refinement receivers are not known yet, so a kind that refines keeps all).
    BlockerFilter keep;
    if (scene.options.cullBeforeSpill && !kind.mayRefine()) keep = makeReachCull(p.samples.lightBounds, p.receivers);
    auto set = std::make_shared<BucketSet>(writeBuckets(*source, planBucketRanges(options, &histogram), options, &buckets,
                                                        [&](std::span<const Triangle> c) {
                                                            if (rescan) kind.rescan(c);
                                                            progress.update(c.size());
                                                        },
                                                        keep));
    progress.done();
    auto replay = std::make_unique<BucketReplaySource>(set, options.readBufferBytes);
    p.replay = replay.get();
    p.blockers = std::make_unique<PrefetchSource>(std::move(replay));
    return p;
}

/// Appends @p extra (refinement receivers) to @p set.
void append(ReceiverSet& set, const ReceiverSet& extra) {
    set.position.insert(set.position.end(), extra.position.begin(), extra.position.end());
    set.normal.insert(set.normal.end(), extra.normal.begin(), extra.normal.end());
    set.pixel.insert(set.pixel.end(), extra.pixel.begin(), extra.pixel.end());
    set.depth.insert(set.depth.end(), extra.depth.begin(), extra.depth.end());
}

/// One bake's state, filled stage by stage.
struct Bake {
    const SceneDesc& scene;
    const BakeSettings& settings;
    const CasterEntry& method;
    int threads;
    BakeBudget budget;
    std::unique_ptr<ReceiverKind> kind;
    MemoryDemand demand;
    uint64_t minimum = 0;  ///< the largest minimum budget any stage found
    MemoryPlan plan;
    Prepared p;
    BucketStats buckets;
    ReceiverResults results;
    VisibilityMasks masks;  ///< every receiver's masks, for --dump only
    std::unique_ptr<Caster> caster;
    size_t firstPass = 0;  ///< receivers of the first pass; later ones are a refinement's
    double streamSeconds = 0, castSeconds = 0, refineSeconds = 0;

    Bake(const SceneDesc& s, const BakeSettings& b)
        : scene(s), settings(b), method(casterEntry(b.method)),
          threads(b.threads > 0 ? b.threads : int(tbb::info::default_concurrency())),
          budget(fitAddressSpace(b.memoryBudget, threads, b.quiet)) {}
    bool dump() const { return !settings.dumpDir.empty(); }
    void replan() {
        plan = budget.plan(demand);
        minimum = std::max(minimum, plan.minimumBudget);
        plan.minimumBudget = minimum;
    }
};

/// Plan, scan, bucket: the receivers and light samples, and the blockers ready to replay. The
/// worst case is checked before any work, the exact plan once the scan has found the receivers
/// (BakeMemory.h).
void scanScene(Bake& b) {
    const SceneDesc& scene = b.scene;
    b.kind = makeReceiverKind(scene.receivers, scene);
    if (!b.method.traits.masks && b.dump())
        fail("--dump", "--method {} gives visible fractions, not per-sample masks", b.method.name);
    TriangleSourcePtr geometry = openSceneGeometry(scene);
    b.demand = demandBeforeScan(scene, *b.kind, *geometry, b.dump());
    checkBeforeScan(b.demand, b.budget);
    // Without a budget the machine is the bound: refuse before any work what it cannot hold.
    checkMemoryFits(scene.file, "the scan pass", scanPhaseBytes(b.demand));
    checkMemoryFits(scene.file, "casting", planMemory(b.demand, 0).minimumBudget);
    auto afterScan = [&](const Prepared& prepared, uint64_t triangles) {
        b.demand.receivers = prepared.receivers.size();
        b.demand.kindBytes = b.kind->maxResidentBytes(b.demand.receivers, triangles);
        b.demand.outputBytes = b.kind->outputBytes(b.demand.receivers);
        if (b.method.memory) b.demand.methodBytes = b.method.memory(triangles, prepared.samples, scene.bakeOptions);
        addSampleDemand(b.demand, prepared.samples, scene);
        b.minimum = b.budget.plan(b.demand).minimumBudget;
    };
    b.p = prepare(scene, b.settings, *b.kind, std::move(geometry), afterScan, b.streamSeconds, b.buckets);
    b.demand.kindBytes = b.kind->residentBytes();
    b.replan();
    checkMemoryFits(scene.file, "casting", b.plan.minimumBudget);
    b.results.resize(b.p.receivers.size(), int(b.p.lights.size()));
    if (b.dump()) b.masks = VisibilityMasks(b.p.receivers.size(), b.p.samples.groupCount());
    b.firstPass = b.p.receivers.size();
}

/// Casts receivers [first, end) with the bake's method, shading each as its result arrives.
void castReceivers(Bake& b, uint32_t first) {
    ScopedTimer timer(b.castSeconds);
    Prepared& p = b.p;
    if (!b.caster) {
        CastContext context{p.samples, p.receivers,       p.sampleSets,      p.options, b.scene.bakeOptions,
                            b.threads, b.plan.tiles,      b.settings.quiet, {},        nullptr};
        if (b.kind->wantsCastChunks()) context.observeChunk = [&b](std::span<const Triangle> c) { b.kind->castChunk(c); };
        b.caster = b.method.make(context);
    }
    const ReceiverShader shader(p.lights, p.samples, p.receivers, p.sampleSets);
    CastSink sink;
    sink.masks = [&](uint32_t r, const uint64_t* words, bool full) {
        shader.shade(r, words, full, b.results);
        if (b.dump())
            for (int k = 0; k < b.masks.groups; ++k)
                b.masks.row(r)[k] = full ? p.samples.groups[k].fullMask() : (words ? words[k] : 0);
    };
    b.caster->cast(*p.blockers, first, sink);
}

/// Adaptive refinement: the kind looks at the first pass, finds its new receivers in one more read
/// of the blockers, and only those are cast. @return whether receivers were added.
bool refineReceivers(Bake& b) {
    Prepared& p = b.p;
    if (!b.kind->refine(p.receivers, b.results)) return false;
    b.demand.kindBytes = b.kind->residentBytes() + b.kind->refineBytes();
    b.replan();  // the refinement's rasterizer fits, or a clear error
    {
        ScopedTimer timer(b.refineSeconds);
        p.blockers->rewind();
        std::vector<Triangle> chunk(kTriangleChunk);
        while (size_t n = p.blockers->read(chunk)) b.kind->refineScan(std::span<const Triangle>(chunk.data(), n));
        append(p.receivers, b.kind->refinedReceivers());
    }
    returnFreedMemory();
    for (size_t i = b.firstPass; i < p.receivers.size(); ++i)
        p.sampleSets.push_back(uint32_t(sampleSetOf(i, p.samples.sets, b.scene.seed)));
    b.results.extend(p.receivers.size());
    if (b.masks.groups) b.masks.words.resize(p.receivers.size() * size_t(b.masks.groups), 0);
    b.demand.receivers = p.receivers.size();
    b.demand.kindBytes = b.kind->residentBytes();
    b.demand.outputBytes = b.kind->outputBytes(p.receivers.size());
    b.replan();
    return true;
}

void writeOutputs(Bake& b) {
    const Prepared& p = b.p;
    b.kind->write(OutputContext{b.scene, p.receivers, p.samples, b.results, b.scene.output, b.firstPass});
    if (b.dump()) writeBakeDump(b.settings.dumpDir, p.receivers, p.sampleSets, p.samples, b.masks, receiverEpsilonOf(p.options));
}

}  // namespace

nlohmann::json runBake(const SceneDesc& scene, const BakeSettings& settings) {
    InputScope inputs;  // no output may replace a file this bake reads
    if (settings.threads < 0 || settings.threads > kMaxThreads)
        fail("--threads", "must be in 0..{} (0: all cores), got {}", kMaxThreads, settings.threads);
    checkBakeOutputs(scene, settings.statsPath, settings.dumpDir);
    Stopwatch total;
    Bake b(scene, settings);
    tbb::global_control parallelism(tbb::global_control::max_allowed_parallelism, size_t(b.threads));
    tbb::global_control stacks(tbb::global_control::thread_stack_size, size_t(kWorkerStackBytes));
    setScratchDirectory(settings.tmpDir);  // spilled OBJ vertices go where the buckets go

    scanScene(b);
    castReceivers(b, 0);
    if (refineReceivers(b)) castReceivers(b, uint32_t(b.firstPass));
    OutputSet outputs;  // every output of the bake appears together, or none does
    writeOutputs(b);

    BakeStatsInputs in{scene, settings.method, b.threads, b.p.receivers, b.p.samples, b.p.options, b.results,
                       b.caster->stats(), b.buckets, b.plan, b.demand};
    in.triangles = b.p.triangleCount, in.replay = b.p.replay, in.openedSolids = &b.p.openedSolids;
    in.streamSeconds = b.streamSeconds, in.castSeconds = b.castSeconds, in.refineSeconds = b.refineSeconds;
    in.totalSeconds = total.seconds();
    nlohmann::json stats = bakeStats(in);
    if (nlohmann::json extra = b.kind->stats(); extra.is_object())
        for (auto& [key, value] : extra.items()) stats[key] = value;
    if (nlohmann::json extra = b.caster->methodStats(); !extra.is_null()) stats[settings.method] = extra;
    if (!settings.statsPath.empty()) writeStats(settings.statsPath, stats);
    outputs.commit();
    return stats;
}

}  // namespace penumbra
