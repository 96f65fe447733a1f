#include "bake/Pipeline.h"

#include "bake/BakeWarnings.h"

#include "bake/output/BakeDump.h"
#include "bake/output/ImageWriters.h"
#include "bake/BakeMemory.h"
#include "bake/BakeOutputs.h"
#include "bake/BakeStats.h"
#include "bake/MemoryPlan.h"
#include "bake/TbbControl.h"
#include "bake/kinds/ReceiverKind.h"
#include "bake/shading/ReceiverShading.h"
#include "bake/WorkPlan.h"
#include "bake/cast/Caster.h"
#include "bake/cast/ClosedSolids.h"
#include "bake/cast/ReachCull.h"
#include "bake/cast/TranslucentBlockers.h"
#include "bake/cast/VisibilityMasks.h"
#include "bake/light/SunLight.h"
#include "bake/shard/ShardedCast.h"
#include "bucket/BucketPlan.h"
#include "stream/util/AnonymousFile.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/InputFile.h"
#include "stream/util/Memory.h"
#include "stream/util/Npy.h"
#include "stream/BlockCyclicSource.h"
#include "stream/PrefetchSource.h"
#include "stream/Translucency.h"
#include "stream/util/Progress.h"
#include "stream/util/StopRequest.h"

#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string_view>
#include <system_error>

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
    /// Translucent triangles the scan saw (casting ones): the translucent pass holds at most these.
    uint64_t translucentScanned = 0;
    uint64_t blockersCast = 0;            ///< triangleCount, or a by-blockers shard's share of it
    std::vector<std::string> warnings;    ///< BakeWarnings.h, printed and in the stats
};

/// Rejects NaN/inf vertices as they stream by, naming the triangle's position in the stream, grows
/// the scene's bounding box and counts the casting translucent triangles (the translucent pass's
/// memory), all in one visit of each triangle.
class FiniteCheck {
public:
    explicit FiniteCheck(const SceneDesc& scene) : scene_(scene) {}
    void operator()(std::span<const Triangle> chunk) {
        for (size_t i = 0; i < chunk.size(); ++i) {
            if (!isFinite(chunk[i]))
                fail(scene_.file, "geometry triangle {} has a non-finite (NaN or infinite) vertex", seen_ + i);
            for (const glm::vec3& v : chunk[i].v) lo_ = glm::min(lo_, v), hi_ = glm::max(hi_, v);
            translucent_ += !(chunk[i].flags & kTriangleNoCast) && isTranslucentId(alphaIdOf(chunk[i].flags));
        }
        seen_ += chunk.size();
    }
    SceneBox box() const {
        SceneBox b;
        if (seen_) b.add(glm::dvec3(lo_)), b.add(glm::dvec3(hi_));
        return b;
    }
    uint64_t translucent() const { return translucent_; }

private:
    const SceneDesc& scene_;
    uint64_t seen_ = 0;
    uint64_t translucent_ = 0;
    glm::vec3 lo_{INFINITY}, hi_{-INFINITY};
};

/// What the translucent pass holds for @p triangles translucent blockers: each twice (the copy the
/// replay view collects and the cast form), and a row of depths per thread. Counted in the scan,
/// so that the plan made after it already holds it: with every cut-out counted after the bucket
/// pass instead, a budget that the first refusal named was refused again, with a larger number.
uint64_t translucentBytes(uint64_t triangles, int threads, const LightSamples& samples) {
    if (triangles == 0) return 0;
    return triangles * (sizeof(Triangle) + TranslucentBlockers::bytesFor(1)) +
           uint64_t(threads) * uint64_t(samples.sampleCount) * 3 * sizeof(uint32_t);
}

/// Rejects a receiver that a receiver_offset moved past the float range (the kinds check their own
/// inputs, but an offset of 1e39 along a normal makes an infinite receiver out of a finite one,
/// and the hierarchy cannot hold it).
void checkReceiversFinite(const SceneDesc& scene, const ReceiverSet& receivers) {
    for (size_t r = 0; r < receivers.size(); ++r) {
        const glm::vec3& p = receivers.position[r];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            fail(scene.file, "receiver {} lies at a non-finite position: a geometry entry's receiver_offset moves it past "
                             "the float range (about 3.4e38)", r);
    }
}

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

/// Every chunk of @p source to the kind's @p pass, with the chunk's geometry entry when the
/// source is in stream order (@p streamOrder).
void feedPass(ReceiverKind& kind, StreamPass pass, TriangleSource& source, bool streamOrder, ProgressReporter* progress = nullptr) {
    std::vector<Triangle> chunk(kTriangleChunk);
    while (size_t n = source.read(chunk)) {
        kind.consume(pass, StreamChunk{std::span<const Triangle>(chunk.data(), n), streamOrder ? source.part() : kAnyGeometryEntry});
        if (progress) progress->update(n);
        throwIfStopRequested("pass over the geometry");
    }
}

/// Whether the bucket pass drops the blockers out of every light's reach: they are culled against
/// every receiver once the scan has found them, so a kind that refines keeps all (its refinement
/// receivers are not known yet), unless this is a shard (the merge casts the refinement).
bool cullsBeforeSpill(const SceneDesc& scene, const ReceiverKind& kind, const BakeSettings& settings) {
    return scene.options.cullBeforeSpill && (!kind.mayRefine() || settings.shard.casting());
}

/// @p keep, and also dropping "cast_shadows": false triangles when no later pass of the kind reads
/// the blockers (its cast pass, a refinement): then they are worth no bucket space.
BlockerFilter withoutNonCasting(const SceneDesc& scene, const ReceiverKind& kind, BlockerFilter keep) {
    const bool any = std::any_of(scene.geometry.begin(), scene.geometry.end(), [](const GeometryDesc& g) { return !g.castShadows; });
    if (!any || kind.wantsPass(StreamPass::Cast) || kind.mayRefine()) return keep;
    if (!keep) return [](const Triangle& t) { return !(t.flags & kTriangleNoCast); };
    return [cull = std::move(keep)](const Triangle& t) { return !(t.flags & kTriangleNoCast) && cull(t); };
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
    auto prefetch = std::make_unique<PrefetchSource>(std::move(geometry));
    PrefetchSource& readAhead = *prefetch;
    TriangleSourcePtr source = std::move(prefetch);
    // Before any triangle is read: the bucket files must fit on disk, and hours of work are announced.
    checkBucketDisk(settings.tmpDir, source->sizeHint(), scene.options.sortBlockers && casterEntry(settings.method).traits.sortedBlockers,
                    cullsBeforeSpill(scene, kind, settings));
    uint64_t samples = 0;
    for (const LightDesc& light : scene.lights) samples += uint64_t(std::max(light.samples, 0));
    noteLongBake(source->sizeHint().value_or(0), kind.receiverBound().value_or(0), samples, 1,
                 int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)), settings.quiet);
    AreaHistogram histogram;
    {
        ScopedTimer timer(streamSeconds);
        ProgressReporter progress("scan", source->sizeHint().value_or(0), settings.quiet);
        FiniteCheck check(scene);
        ClosedSolidScan solids(p.samples);
        const bool scanPass = kind.wantsPass(StreamPass::Scan);
        std::vector<Triangle> chunk(kTriangleChunk);
        while (size_t n = source->read(chunk)) {
            std::span<const Triangle> part(chunk.data(), n);
            check(part);
            histogram.add(part);
            if (scanPass) kind.consume(StreamPass::Scan, StreamChunk{part, source->part()});
            if (scene.options.closedCasters) solids.scan(part, source->part());
            progress.update(n);
            testPoint("scan");
            throwIfStopRequested("scan");
        }
        progress.done();  // the kind's own work after the scan (an atlas) is a phase of its own
        p.receivers = kind.receivers();
        checkReceiversFinite(scene, p.receivers);
        p.openedSolids = solids.finish();
        p.options.epsilonLength = epsilonLength(p.receivers, check.box());
        p.translucentScanned = check.translucent();
    }
    reportOpenedSolids(p.openedSolids, p.lights, settings.quiet);
    if (const double epsilonMax = p.options.epsilon * p.options.epsilonLength;
        p.options.closedCasters && !closedCastersSafe(p.openedSolids, epsilonMax)) {
        p.options.closedCasters = false;
        p.openedSolids.castersOffForScale = true;
        if (!settings.quiet)
            printNote("closed casters are off: the rule's receiver epsilon ({:.3g}) is more than {:g} % of the smallest closed "
                      "solid ({:.3g} across), where skipping faces could lose shadows (far from the origin, epsilon grows "
                      "with the coordinates)",
                      epsilonMax, 100 * kClosedEpsilonShare, p.openedSolids.smallestExtent);
    }
    p.warnings = bakeWarnings(scene.receivers, p.receivers, p.lights);
    if (auto far = epsilonWarning(p.receivers, p.options.epsilon, p.options.epsilonLength)) p.warnings.push_back(std::move(*far));
    for (std::string& warning : leakySolidWarnings(p.openedSolids, scene)) p.warnings.push_back(std::move(warning));
    for (const std::string& warning : p.warnings) printWarning("{}", warning);
    returnFreedMemory();  // the z-buffer is gone; keep it from inflating the casting phase's RSS
    p.sampleSets.resize(p.receivers.size());
    for (size_t i = 0; i < p.receivers.size(); ++i) p.sampleSets[i] = uint32_t(sampleSetOf(i, p.samples.sets, scene.seed));
    p.triangleCount = histogram.count();
    afterScan(p, p.triangleCount);  // the exact memory check, before the bucket pass writes anything

    // A by-blockers shard casts its share of the stream, and makes or reads only that share
    // where the source can skip; closed solids are counted over the whole stream, so with solids
    // to open the share is taken above them.
    const std::optional<BlockShare> share =
        blockerShareOf(settings.shard, p.receivers.size(), p.triangleCount, casterEntry(settings.method).traits.memoryTiles);
    const bool solids = !p.openedSolids.ordinals.empty();
    auto takeShare = [&](TriangleSourcePtr all) -> TriangleSourcePtr { return std::make_unique<BlockCyclicSource>(std::move(all), *share); };
    if (share && !solids) readAhead.rewindWrapped(takeShare);
    else source->rewind();
    if (solids) source = std::make_unique<OpenSolidsSource>(std::move(source), p.openedSolids.ordinals);
    if (share && solids) source = takeShare(std::move(source));
    p.blockersCast = share ? share->triangles(p.triangleCount) : p.triangleCount;
    // A method that gains nothing from largest-first order (it holds or streams the scene in any
    // order) skips the bucket pass.
    // A merge casts nothing but a refinement's receivers: it replays the source as it is, unless
    // the kind must see the culled replay a cast would have seen (its cast pass, a refinement).
    // A shard writes masks only: the kind's passes for its outputs are the merge's to make.
    const bool shard = settings.shard.casting();
    const bool rescan = kind.wantsPass(StreamPass::Rescan) && !shard;
    const bool replaySource = settings.shard.merge && !kind.mayRefine() && !kind.wantsPass(StreamPass::Cast);
    if (replaySource || !scene.options.sortBlockers || !casterEntry(settings.method).traits.sortedBlockers) {  // replay the source itself
        if (rescan) {  // no bucket pass to ride along with: a read of its own
            feedPass(kind, StreamPass::Rescan, *source, true);
            source->rewind();
        }
        p.blockers = std::move(source);  // already read ahead
        return p;
    }
    BucketOptions options;
    options.tmpDir = settings.tmpDir;
    options.keep = settings.keepBuckets;
    ProgressReporter progress("bucket", p.blockersCast, settings.quiet);
    // A receiver kind that wants a second look at the geometry (smooth shading) gets it during
    // the bucket pass, so the source is still read only twice.
    // What cannot block is never written: the reach culls, against every receiver, once the scan
    // has found them (refinement receivers are not known yet, so a kind that refines keeps all;
    // a shard never refines: the merge casts the refinement).
    BlockerFilter keep;
    if (cullsBeforeSpill(scene, kind, settings)) keep = makeReachCull(p.samples.lightBounds, p.receivers);
    keep = withoutNonCasting(scene, kind, std::move(keep));
    auto set = std::make_shared<BucketSet>(writeBuckets(*source, planBucketRanges(options, &histogram), options, &buckets,
                                                        [&](std::span<const Triangle> c) {
                                                            if (rescan) kind.consume(StreamPass::Rescan, StreamChunk{c, source->part()});
                                                            progress.update(c.size());
                                                            testPoint("bucket");
                                                            throwIfStopRequested("bucket pass");
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
    if (!set.unshadowed.empty() || !extra.unshadowed.empty()) {  // either may be empty: all receive
        set.unshadowed.resize(set.size() - extra.size(), 0);
        if (extra.unshadowed.empty()) set.unshadowed.resize(set.size(), 0);
        else set.unshadowed.insert(set.unshadowed.end(), extra.unshadowed.begin(), extra.unshadowed.end());
    }
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
    std::unique_ptr<ShardedCast> sharded;  ///< shards, merges and checkpoints, else null
    TileHooks tileHooks;
    /// Coloured translucent blockers (TranslucentBlockers.h): the replay as methods see it, and
    /// its translucent triangles once the first cast has read them all.
    std::unique_ptr<OpaqueOnlySource> opaqueView;
    std::unique_ptr<TranslucentBlockers> translucent;
    std::once_flag translucentOnce;
    size_t firstPass = 0;  ///< receivers of the first pass; later ones are a refinement's
    double streamSeconds = 0, castSeconds = 0, refineSeconds = 0;

    Bake(const SceneDesc& s, const BakeSettings& b)
        : scene(s), settings(b), method(casterEntry(b.method)),
          threads(b.threads > 0 ? b.threads : int(tbb::info::default_concurrency())),
          budget(fitAddressSpace(b.memoryBudget, threads, b.quiet)) {
        budget.where = s.file;
    }
    bool dump() const { return !settings.dumpDir.empty(); }
    /// Every receiver's masks are kept: for the dump, a shard file, checkpoints, or a library
    /// caller that asked.
    bool keepMasks() const {
        return dump() || ShardedCast::keepsMasks(settings.shard) || (settings.capture && settings.capture->wantMasks);
    }
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
    b.kind->setQuiet(b.settings.quiet);
    if (b.method.traits.needsPolygons && !b.kind->receiverPolygons())
        fail("--method " + b.method.name, "applies to lightmap receivers only (this scene's receivers are \"{}\")",
             scene.receivers.value("type", std::string("?")));
    if (!b.method.traits.masks && b.dump())
        fail("--dump", "--method {} gives visible fractions, not per-sample masks", b.method.name);
    if (!b.method.traits.masks && ShardedCast::keepsMasks(b.settings.shard))
        fail(b.settings.shard.merge ? "merge" : b.settings.shard.count ? "--shard" : "--checkpoint",
             "--method {} gives visible fractions, not per-sample masks to merge", b.method.name);
    if (b.settings.shard.casting() && b.dump()) fail("--dump", "a shard writes no outputs; give --dump to penumbra merge");
    TriangleSourcePtr geometry =
        openCheckedBeforeScan(scene, *b.kind, b.budget, b.keepMasks(), b.settings.quiet, b.demand, b.method.memory);
    // Without a budget the machine is the bound: refuse before any work what it cannot hold.
    checkMemoryFits(scene.file, "the scan pass", scanPhaseBytes(b.demand));
    checkAddressSpaceLeft(scene.file, "the scan pass", scanPhaseBytes(b.demand),
                          b.budget.overhead ? leastNamedLimit(b.demand, b.budget) : 0);
    checkMemoryFits(scene.file, "casting", planMemory(b.demand, 0).minimumBudget);
    auto afterScan = [&](const Prepared& prepared, uint64_t triangles) {
        b.demand.receivers = prepared.receivers.size();
        b.demand.kindBytes = b.kind->maxResidentBytes(b.demand.receivers, triangles);
        b.demand.outputBytes = b.kind->outputBytes(b.demand.receivers);
        if (b.method.memory) b.demand.methodBytes = b.method.memory(triangles, prepared.receivers.size(), prepared.samples, scene.bakeOptions);
        addSampleDemand(b.demand, prepared.samples, scene);
        b.demand.translucentBytes = translucentBytes(prepared.translucentScanned, b.threads, prepared.samples);
        b.minimum = b.budget.plan(b.demand).minimumBudget;
    };
    b.p = prepare(scene, b.settings, *b.kind, std::move(geometry), afterScan, b.streamSeconds, b.buckets);
    b.demand.kindBytes = b.kind->residentBytes();
    b.demand.translucentBytes = translucentBytes(b.p.translucentScanned, b.threads, b.p.samples);
    b.replan();
    checkMemoryFits(scene.file, "casting", b.plan.minimumBudget);
    b.results.resize(b.p.receivers.size(), int(b.p.lights.size()));
    if (b.keepMasks()) b.masks = VisibilityMasks(b.p.receivers.size(), b.p.samples.groupCount());
    b.firstPass = b.p.receivers.size();
    if (ShardedCast::keepsMasks(b.settings.shard)) {
        const std::string methodKey = b.method.name + (scene.options.embreeRuleFilter ? "" : ":embree-native");
        b.sharded = std::make_unique<ShardedCast>(b.settings.shard, scene.file, methodKey, b.method.traits.memoryTiles,
                                                  b.p.receivers, b.p.sampleSets, b.p.samples, b.settings.quiet);
    }
}

void makeCaster(Bake& b) {
    Prepared& p = b.p;
    if (b.caster) return;
    CastContext context{p.samples, p.receivers,       p.sampleSets,      p.options, b.scene.bakeOptions,
                        b.threads, b.plan.tiles,      b.settings.quiet, {},        nullptr};
    // A merge gives the kind its pass over the faces itself (mergeShards), once.
    if (b.kind->wantsPass(StreamPass::Cast) && !b.settings.shard.merge && !b.settings.shard.casting())
        context.observeChunk = [&b](std::span<const Triangle> c) { b.kind->consume(StreamPass::Cast, StreamChunk{c}); };
    if (b.sharded) context.tileHooks = &b.tileHooks;
    if (b.method.traits.needsPolygons) context.polygons = b.kind->receiverPolygons();
    b.caster = b.method.make(context);
}

/// The translucent blockers the replay held, once a method has read it whole; refuses what
/// cannot carry them (translucentPass()). Null: none, or the method weighs them itself.
const TranslucentBlockers* translucentBlockers(Bake& b) {
    std::call_once(b.translucentOnce, [&b] {
        const char* partialFiles = !b.sharded ? nullptr : b.settings.shard.count ? "--shard" : "--checkpoint";
        b.translucent = translucentPass(*b.opaqueView, b.p.samples, b.method.name, b.method.traits, partialFiles);
    });
    return b.translucent.get();
}

/// Keeps receiver @p r's mask when the bake keeps masks (Bake::keepMasks).
void keepMasks(Bake& b, uint32_t r, const uint64_t* words, bool full) {
    if (!b.keepMasks()) return;
    for (int k = 0; k < b.masks.groups; ++k) b.masks.row(r)[k] = full ? b.p.samples.groups[k].fullMask() : (words ? words[k] : 0);
}

/// Casts receivers [first, end) with the bake's method, shading each as its result arrives.
void castReceivers(Bake& b, uint32_t first) {
    ScopedTimer timer(b.castSeconds);
    Prepared& p = b.p;
    const ReceiverShader shader(p.lights, p.samples, p.receivers, p.sampleSets);
    if (b.sharded)  // a restored tile's receivers are shaded from their checkpointed masks
        b.tileHooks = b.sharded->tileHooks(b.masks, [&](uint32_t r, const uint64_t* row) { shader.shade(r, row, false, b.results); });
    makeCaster(b);
    // A merge's first cast read no blockers, so the caster takes the replay as ready; the
    // refinement's scan has read it to the end.
    if (first > 0 && b.settings.shard.merge) p.blockers->rewind();
    if (!b.opaqueView) b.opaqueView = std::make_unique<OpaqueOnlySource>(*p.blockers, !b.method.traits.translucency);
    const ReceiverEpsilon epsilon = receiverEpsilonOf(p.options);
    const AlphaTable& alpha = alphaTableOf(p.options);
    CastSink sink;
    sink.masksWithDepth = [&](uint32_t r, const uint64_t* words, bool full, const uint32_t* depth) {
        // A receiver on a "receive_shadows": false entry is unshadowed, whatever the method found.
        if (p.receivers.isUnshadowed(r)) words = nullptr, full = false, depth = nullptr;
        translucentBlockers(b);  // the refusals
        shader.shade(r, words, full, b.results, depth);
        keepMasks(b, r, words, full);
    };
    sink.masks = [&](uint32_t r, const uint64_t* words, bool full) {
        // A receiver on a "receive_shadows": false entry is unshadowed, whatever the method found.
        if (p.receivers.isUnshadowed(r)) words = nullptr, full = false;
        const uint32_t* depth = nullptr;
        if (const TranslucentBlockers* t = translucentBlockers(b)) {
            thread_local std::vector<uint32_t> row;
            row.resize(size_t(p.samples.sampleCount) * 3);
            if (t->depthAt(glm::dvec3(p.receivers.position[r]), int(p.sampleSets[r]), words, full, epsilon, alpha, row)) depth = row.data();
        }
        shader.shade(r, words, full, b.results, depth);
        keepMasks(b, r, words, full);
    };
    const std::vector<float> lit(p.lights.size(), 1.0f);
    // A preview's tint through translucent blockers: 32 samples per light, spread over it, weigh
    // it (a whole light's segments cost as much as the exact methods' pass: docs/translucency.md).
    const std::vector<uint64_t> tintSkip = samplesOutsideSubset(p.samples, 32);
    sink.visibility = [&](uint32_t r, const float* lightVisibility) {
        const bool unshadowed = p.receivers.isUnshadowed(r);
        const uint32_t* depth = nullptr;
        if (const TranslucentBlockers* t = translucentBlockers(b); t && !unshadowed) {
            thread_local std::vector<uint32_t> row;
            row.resize(size_t(p.samples.sampleCount) * 3);
            if (t->depthAt(glm::dvec3(p.receivers.position[r]), int(p.sampleSets[r]), tintSkip.data(), false, epsilon, alpha, row))
                depth = row.data();
        }
        shader.shadeVisibleFraction(r, unshadowed ? lit.data() : lightVisibility, b.results, depth, tintSkip.data());
    };
    b.caster->cast(*b.opaqueView, first, sink);
}

/// `penumbra merge`: the first pass's masks come from the shard files, shaded as a cast would.
void mergeShards(Bake& b) {
    ScopedTimer timer(b.castSeconds);
    Prepared& p = b.p;
    makeCaster(b);  // for a refinement's cast, and the stats
    const uint32_t shards = b.sharded->merge(b.masks);
    const ReceiverShader shader(p.lights, p.samples, p.receivers, p.sampleSets);
    tbb::parallel_for(size_t(0), b.firstPass, [&](size_t r) { shader.shade(uint32_t(r), b.masks.row(r), false, b.results); });
    if (b.kind->wantsPass(StreamPass::Cast)) {  // the kind's pass over the faces that the cast would have carried
        p.blockers->rewind();
        feedPass(*b.kind, StreamPass::Cast, *p.blockers, false);
    }
    if (!b.settings.quiet) printNote("merged {} shard(s) of {}", shards, b.settings.shard.dir);
}

/// Adaptive refinement: the kind looks at the first pass, finds its new receivers in one more read
/// of the blockers, and only those are cast. @return whether receivers were added.
bool refineReceivers(Bake& b) {
    Prepared& p = b.p;
    if (!b.kind->refine(p.receivers, b.results)) return false;
    b.demand.kindBytes = b.kind->residentBytes() + b.kind->passBytes(StreamPass::Refine);
    // Its pass, and then its cast and the outputs at worst (every sub-pixel sample a receiver):
    // one check before the pass, so that a budget too small fails once, naming one that works.
    const uint64_t added = b.kind->maxRefinedReceivers(), all = p.receivers.size() + added;
    b.demand.refinement = {added, b.kind->maxResidentBytes(all, p.triangleCount), b.kind->outputBytes(all)};
    b.replan();
    {
        ScopedTimer timer(b.refineSeconds);
        p.blockers->rewind();
        ProgressReporter progress("antialias", p.blockers->sizeHint().value_or(0), b.settings.quiet);
        if (b.kind->wantsPass(StreamPass::Refine)) feedPass(*b.kind, StreamPass::Refine, *p.blockers, false, &progress);
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
    b.demand.refinement = {};
    b.replan();
    return true;
}

void writeOutputs(Bake& b) {
    const Prepared& p = b.p;
    ProgressReporter progress("write", 0, b.settings.quiet);  // a phase of its own: large EXRs take seconds
    if (!b.settings.capture || b.settings.capture->writeOutputs) b.kind->write(OutputContext{b.scene, p.receivers, p.samples, b.results, b.scene.output, b.firstPass});
    testPoint("write");  // the image is finished but not in place: a kill must leave no trace of it
    if (b.dump()) writeBakeDump(b.settings.dumpDir, p.receivers, p.sampleSets, p.samples, b.masks, receiverEpsilonOf(p.options));
    if (!b.settings.visibilityPath.empty()) {
        const uint64_t shape[1] = {p.receivers.size()};
        ensureParentDirectory(b.settings.visibilityPath);  // as --stats and --dump make theirs (README)
        writeNpy(b.settings.visibilityPath, "<f4", shape, b.results.visibility.data(), b.results.visibility.size() * sizeof(float));
    }
}

/// What a bake stopped by SIGTERM (@p stop) leaves, and how to go on: the line the CLI prints.
StopRequested stoppedBake(const Bake& b, const StopRequested& stop) {
    const std::string& dir = b.settings.shard.checkpointDir;
    if (!b.sharded)  // before the cast: the checkpoints of an earlier run, if any, are untouched
        return StopRequested(fmt::format("{}; the checkpoints in {} are kept: run the same command to continue", stop.what(), dir));
    return StopRequested(fmt::format("{}; {} checkpointed in {}: run the same command to continue", stop.what(),
                                     b.sharded->checkpointedWork(), dir));
}

/// Scan, cast (or merge) and refine: the stages a SIGTERM may stop when the bake checkpoints.
void castStages(Bake& b) {
    scanScene(b);
    if (b.settings.shard.merge) mergeShards(b);
    else castReceivers(b, 0);
    // A shard writes its masks, the merge the outputs.
    if (!b.settings.shard.casting() && refineReceivers(b)) castReceivers(b, uint32_t(b.firstPass));
}

}  // namespace

namespace {
nlohmann::json bakeScene(Bake& b, const Stopwatch& total);

/// The plan let through what the allocator could not give (the plan estimates what a bake maps;
/// the process maps more): one line with the least the bake needs, as the plan's refusals say.
[[noreturn]] void failOutOfMemory(const Bake& b) {
    const uint64_t data = std::max(b.minimum, scanPhaseBytes(b.demand));
    const uint64_t limit = addressSpaceLimit();
    if (limit)
        fail(b.scene.file, "out of memory under the address-space limit (prlimit --as, ulimit -v) of {}: this bake needs "
             "at least {}; give it more, or lower the resolution or sample count", formatBytes(limit),
             formatBytes(mappedNotResidentBytes() + 2 * kReadAheadStackBytes + kBaselineBytes + data + data / 4));
    fail(b.scene.file, "out of memory: this bake's data needs at least {} at once; lower the resolution or sample "
         "count, or give --memory-budget to bake in memory tiles", formatBytes(data + data / 4));
}
}  // namespace

nlohmann::json runBake(const SceneDesc& scene, const BakeSettings& settings) {
    InputScope inputs;  // no output may replace a file this bake reads
    if (settings.threads < 0 || settings.threads > kMaxThreads)
        fail("--threads", "must be in 0..{} (0: all cores), got {}", kMaxThreads, settings.threads);
    checkBakeOutputs(scene, settings.statsPath, settings.dumpDir, settings.visibilityPath,
                     {settings.shard.checkpointDir, settings.shard.dir});
    Stopwatch total;
    Bake b(scene, settings);
    try {
        const ScopedTbbControl parallelism(tbb::global_control::max_allowed_parallelism, size_t(b.threads));
        // EXR blocks compressed on as many threads (on FLOWERS at 1280x960 the EXR's deflate was
        // 0.58 s of a 0.7 s output phase, on one core). Not under a memory budget or an
        // address-space limit: the pool's buffers (two blocks per thread) and thread stacks would
        // take room the plan gives to the bake. The pool ends with the bake, so that a process
        // that forks later (Python's multiprocessing) does not hand its child a pool without threads.
        struct ExrThreads {
            explicit ExrThreads(int n) { setExrCompressionThreads(n); }
            ~ExrThreads() { setExrCompressionThreads(0); }
        } exrThreads(b.threads > 1 && settings.memoryBudget == 0 && addressSpaceLimit() == 0 ? b.threads : 0);
        // The workers' stacks; one thread starts no worker, so it sets none.
        const ScopedTbbControl stacks(tbb::global_control::thread_stack_size, b.threads > 1 ? size_t(kWorkerStackBytes) : 0);
        return bakeScene(b, total);
    } catch (const std::bad_alloc&) {
        failOutOfMemory(b);
    } catch (const std::exception& e) {
        // TBB could not start its workers (an address-space or process limit): nothing is
        // committed yet, so bake again on one thread, which starts none.
        if (!retryOnOneThread(e, b.threads, "baking")) throw;
        BakeSettings one = settings;
        one.threads = 1;
        return runBake(scene, one);
    }
}

namespace {

/// The bake's passes, in the parallelism runBake() set up.
nlohmann::json bakeScene(Bake& b, const Stopwatch& total) {
    const SceneDesc& scene = b.scene;
    const BakeSettings& settings = b.settings;
    setScratchDirectory(settings.tmpDir);  // spilled OBJ vertices go where the buckets go

    // With checkpoints the first SIGTERM (Slurm's notice before a time limit) stops the bake at
    // its next chunk, every finished tile on disk, and the CLI exits 143 (StopRequest.h). Only hpc
    // checkpoints (its memory tiles); other methods have nothing to save and keep the immediate exit.
    std::optional<DeferredTermination> deferred;
    if (!settings.shard.checkpointDir.empty() && !settings.shard.merge && b.method.traits.memoryTiles) deferred.emplace();
    try {
        castStages(b);
    } catch (const StopRequested& stop) {
        throw stoppedBake(b, stop);
    }
    // Once cast, a SIGTERM no longer stops the bake: writing takes seconds and saves the most.
    const bool shard = settings.shard.casting();
    OutputSet outputs;  // every output of the bake appears together, or none does
    if (shard) b.sharded->writeShard(b.masks);
    else writeOutputs(b);

    BakeStatsInputs in{scene, settings.method, b.threads, b.p.receivers, b.p.samples, b.p.options, b.results,
                       b.caster->stats(), b.buckets, b.plan, b.demand};
    in.triangles = b.p.triangleCount, in.replay = b.p.replay, in.openedSolids = &b.p.openedSolids;
    in.streamSeconds = b.streamSeconds, in.castSeconds = b.castSeconds, in.refineSeconds = b.refineSeconds;
    in.totalSeconds = total.seconds();
    nlohmann::json stats = bakeStats(in);
    if (nlohmann::json extra = b.kind->stats(); extra.is_object())
        for (auto& [key, value] : extra.items()) stats[key] = value;
    if (nlohmann::json extra = b.caster->methodStats(); !extra.is_null()) stats[settings.method] = extra;
    if (b.sharded) stats["shard"] = b.sharded->stats(), stats["shard"]["blockers_cast"] = b.p.blockersCast;
    if (b.opaqueView && !b.opaqueView->translucent().empty()) {
        const size_t collected = b.opaqueView->translucent().size() * sizeof(Triangle);
        stats["translucent"] = {{"triangles", b.opaqueView->translucent().size()}, {"bytes", collected + (b.translucent ? b.translucent->bytes() : 0)}};
        if (b.translucent) stats["translucent"]["relations_tested"] = b.translucent->tests.load(), stats["translucent"]["crossings"] = b.translucent->crossings.load();
    }
    stats["outputs_written"] = outputs.paths();  // every file of the bake but the stats themselves
    if (!b.p.warnings.empty()) stats["warnings"] = b.p.warnings;
    if (const auto& u = b.p.receivers.unshadowed; !u.empty())  // "receive_shadows": false
        stats["unshadowed_receivers"] = uint64_t(std::count(u.begin(), u.end(), uint8_t(1)));
    if (!settings.statsPath.empty()) writeStats(settings.statsPath, stats);
    outputs.commit();
    if (b.sharded) b.sharded->complete();  // the outputs are in place: no checkpoint is needed
    if (BakeCapture* c = settings.capture) {
        c->receivers = std::move(b.p.receivers), c->samples = std::move(b.p.samples);
        c->sampleSets = std::move(b.p.sampleSets), c->results = std::move(b.results);
        c->masks = std::move(b.masks), c->firstPass = b.firstPass, c->kind = std::move(b.kind);
    }
    return stats;
}

}  // namespace

void writeCapturedOutputs(const SceneDesc& scene, const BakeCapture& c, const std::string& output) {
    // The kind's own check of the new name: a camera's outputs named x.png were an EXR and a PNG
    // for one file.
    SceneDesc renamed = scene;
    renamed.output = output, renamed.outputFromScene = false;
    validateReceiverKind(scene.receivers, renamed);
    requireOutputFolder("write", output);  // as -o: a missing folder is more often a typo
    InputScope inputs;
    OutputSet outputs;
    c.kind->write(OutputContext{scene, c.receivers, c.samples, c.results, output, c.firstPass});
    outputs.commit();
}

}  // namespace penumbra
