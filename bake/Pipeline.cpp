#include "bake/Pipeline.h"

#include "bake/ScenePasses.h"

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
#include "bake/cast/TranslucentBlockers.h"
#include "bake/cast/VisibilityMasks.h"
#include "bake/shard/ShardedCast.h"
#include "bucket/BucketPlan.h"
#include "stream/util/AnonymousFile.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/InputFile.h"
#include "stream/util/Memory.h"
#include "stream/util/Npy.h"
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

/// The bake's outputs checked together (checkBakeOutputs()): before any work, and with @p kindFiles
/// once the scan has named them.
void checkOutputsOf(const SceneDesc& scene, const BakeSettings& settings, const std::vector<std::string>& kindFiles = {}) {
    checkBakeOutputs(scene, settings.statsPath, settings.dumpDir, settings.visibilityPath,
                     {settings.shard.checkpointDir, settings.shard.dir}, kindFiles);
}

/// What the translucent pass holds for @p triangles translucent blockers: each twice (the copy the
/// replay view collects and the cast form), and a row of depths per thread. Counted in the scan,
/// so that the plan made after it already holds it: with every cut-out counted after the bucket
/// pass instead, a budget that the first refusal named was refused again, with a larger number.
uint64_t translucentBytes(uint64_t triangles, int threads, const LightSamples& samples) {
    if (triangles == 0) return 0;
    return triangles * sizeof(Triangle) + TranslucentBlockers::bytesFor(triangles, samples.groups.size()) +
           uint64_t(threads) * uint64_t(samples.sampleCount) * 3 * sizeof(uint32_t);
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
    /// The masks kept whole (keepMasks()): every receiver's, or only castShare's
    VisibilityMasks masks;
    /// A by-receivers shard's receivers (receiverShareOf()), found after the scan; else empty.
    std::optional<std::vector<uint32_t>> castShare;
    std::unique_ptr<Caster> caster;
    std::unique_ptr<ShardedCast> sharded;  ///< shards, merges and checkpoints, else null
    TileHooks tileHooks;
    /// Coloured translucent blockers (TranslucentBlockers.h): the replay as methods see it, and
    /// its translucent triangles once the first cast has read them all.
    std::unique_ptr<OpaqueOnlySource> opaqueView;
    std::unique_ptr<TranslucentBlockers> translucent;
    std::once_flag translucentOnce;
    size_t firstPass = 0;  ///< receivers of the first pass; later ones are a refinement's
    double openSeconds = 0, streamSeconds = 0, castSeconds = 0, refineSeconds = 0;

    Bake(const SceneDesc& s, const BakeSettings& b)
        : scene(s), settings(b), method(casterEntry(b.method)),
          threads(b.threads > 0 ? b.threads : int(tbb::info::default_concurrency())),
          budget(fitAddressSpace(b.memoryBudget, threads, /*quiet=*/true, b.threadsWanted)) {
        budget.where = s.file, budget.threads = threads;  // the warning of fewer threads once the pre-scan check passes
    }
    bool dump() const { return !settings.dumpDir.empty(); }
    /// Every receiver's masks are kept: for the dump, a shard file, checkpoints, or a library
    /// caller that asked.
    bool keepMasks() const {
        return dump() || ShardedCast::keepsMasks(settings.shard) || (settings.capture && settings.capture->wantMasks);
    }
    /// Masks kept for a by-receivers shard's share only: nobody asked for every receiver's.
    bool keepsShareOnly() const { return castShare && !dump() && !(settings.capture && settings.capture->wantMasks); }
    MaskKeeping maskKeeping() const {
        const bool library = settings.capture && settings.capture->wantMasks;
        return {keepMasks(), dump() || library ? 1u : receiverSharesBeforeScan(settings.shard, method.traits.memoryTiles)};
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
    // Checkpoints are hpc's finished memory tiles: another method would save nothing and lose
    // its whole cast to a SIGTERM, while the user believed it safe.
    if (!b.settings.shard.checkpointDir.empty() && !b.settings.shard.merge && !b.method.traits.memoryTiles)
        fail(b.settings.shard.resume ? "--resume" : "--checkpoint",
             "--method {} has no memory tiles to save; only hpc checkpoints (bake without it{})", b.method.name,
             b.method.traits.masks ? ", or shard the bake" : "");  // a method without masks cannot shard either
    if (!b.method.traits.masks && ShardedCast::keepsMasks(b.settings.shard))
        fail(b.settings.shard.merge ? "merge" : "--shard", "--method {} gives visible fractions, not per-sample masks to merge",
             b.method.name);
    if (b.settings.shard.casting() && b.dump()) fail("--dump", "a shard writes no outputs; give --dump to penumbra merge");
    TriangleSourcePtr geometry = [&] {
        ScopedTimer timer(b.openSeconds);
        TriangleSourcePtr opened = openCheckedBeforeScan(scene, *b.kind, b.budget, b.maskKeeping(), b.settings.quiet, b.demand, b.method.memory);
        warnFewerThreads(b.budget, b.settings.quiet);
        return opened;
    }();
    // Without a budget the machine is the bound: refuse before any work what it cannot hold.
    checkMemoryFits(scene.file, "the scan pass", scanPhaseBytes(b.demand));
    checkAddressSpaceLeft(scene.file, "the scan pass", scanPhaseBytes(b.demand),
                          b.budget.overhead ? leastNamedLimit(b.demand, b.budget) : 0);
    checkMemoryFits(scene.file, "casting", planMemory(b.demand, 0).minimumBudget);
    auto afterScan = [&](const Prepared& prepared, uint64_t triangles) {
        // The files the scan named (a lightmap's per-mesh maps) against the other outputs now,
        // not when they are put in place after the cast.
        if (!b.settings.shard.casting())
            if (const std::vector<std::string> files = b.kind->outputFiles(scene.output); !files.empty())
                checkOutputsOf(scene, b.settings, files);
        b.demand.receivers = prepared.receivers.size();
        b.demand.kindBytes = b.kind->maxResidentBytes(b.demand.receivers, triangles);
        b.demand.outputBytes = b.kind->outputBytes(b.demand.receivers);
        if (b.method.memory) b.demand.methodBytes = b.method.memory(triangles, prepared.receivers.size(), prepared.samples, scene.bakeOptions);
        addSampleDemand(b.demand, prepared.samples, scene);
        b.demand.translucentBytes = translucentBytes(prepared.translucentScanned, b.threads, prepared.samples);
        // A by-receivers shard's tiles cut its share, and it keeps masks for its share only.
        b.castShare = receiverShareOf(b.settings.shard, prepared.receivers, b.method.traits.memoryTiles);
        b.demand.castReceivers = b.castShare ? b.castShare->size() : 0;
        b.demand.maskRows = b.keepsShareOnly() ? b.castShare->size() : 0;
        b.minimum = b.budget.plan(b.demand).minimumBudget;
    };
    b.p = prepare(scene, b.settings, *b.kind, std::move(geometry), afterScan, b.streamSeconds, b.buckets);
    b.demand.kindBytes = b.kind->residentBytes();
    b.demand.translucentBytes = translucentBytes(b.p.translucentScanned, b.threads, b.p.samples);
    b.replan();
    checkMemoryFits(scene.file, "casting", b.plan.minimumBudget);
    b.results.resize(b.p.receivers.size(), int(b.p.lights.size()));
    if (b.keepsShareOnly()) b.masks = VisibilityMasks(b.p.receivers.size(), b.p.samples.groupCount(), *b.castShare);
    else if (b.keepMasks()) b.masks = VisibilityMasks(b.p.receivers.size(), b.p.samples.groupCount());
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
    context.subTilesPerThread = b.plan.subTilesPerThread;
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
        // The blocks built once speed the pass up (3x on examples/glass.json) but are not needed:
        // under a budget they take only what the plan leaves spare, so that they never change
        // what a budget admits (the translucent triangles are counted only after the scan: blocks
        // in the plan would make a budget that the first refusal named fail a second time).
        const uint64_t cacheBytes = std::min(TranslucentBlockers::kCachedBlockBytes, b.budget.bytes == 0 ? UINT64_MAX : b.plan.spareBytes);
        b.translucent = translucentPass(*b.opaqueView, b.p.samples, b.method.name, b.method.traits, partialFiles, b.p.options.simd,
                                        cacheBytes);
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
        b.tileHooks = b.sharded->tileHooks(b.masks, [&](std::span<const uint32_t> ids) {
            shadeEach(ids.size(), b.settings.quiet, [&](size_t i) { shader.shade(ids[i], b.masks.row(ids[i]), false, b.results); });
        });
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
    shadeEach(b.firstPass, b.settings.quiet, [&](size_t r) { shader.shade(uint32_t(r), b.masks.row(r), false, b.results); });
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
    if (b.masks.groups && b.masks.rowOf.empty()) b.masks.words.resize(p.receivers.size() * size_t(b.masks.groups), 0);
    b.demand.receivers = p.receivers.size();
    b.demand.kindBytes = b.kind->residentBytes();
    b.demand.outputBytes = b.kind->outputBytes(p.receivers.size());
    b.demand.refinement = {};
    b.replan();
    return true;
}

void writeOutputs(Bake& b) {
    const Prepared& p = b.p;
    // A phase of its own: large EXRs take seconds (a camera reports its rows).
    ProgressReporter progress("write", b.kind->outputWork(), b.settings.quiet);
    if (!b.settings.capture || b.settings.capture->writeOutputs)
        b.kind->write(OutputContext{b.scene, p.receivers, p.samples, b.results, b.scene.output, b.firstPass, &progress});
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
    if (limit) {
        const uint64_t need = mappedNotResidentBytes() + 2 * kReadAheadStackBytes + kBaselineBytes + data + data / 4;
        // A need at or below the limit would contradict the failure: the plan had not yet seen
        // what failed (a file's parse, as it was being opened).
        fail(b.scene.file, "out of memory under the address-space limit (prlimit --as, ulimit -v) of {}: this bake needs "
             "{}; give it more, or lower the resolution or sample count", formatBytes(limit),
             need <= limit ? std::string("more than that") : "at least " + formatBytes(need));
    }
    fail(b.scene.file, "out of memory: this bake's data needs at least {} at once; lower the resolution or sample "
         "count, or give --memory-budget to bake in memory tiles", formatBytes(data + data / 4));
}
}  // namespace

nlohmann::json runBake(const SceneDesc& scene, const BakeSettings& settings) {
    InputScope inputs;  // no output may replace a file this bake reads
    if (settings.threads < 0 || settings.threads > kMaxThreads)
        fail("--threads", "must be in 0..{} (0: all cores), got {}", kMaxThreads, settings.threads);
    checkOutputsOf(scene, settings);
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
    } catch (const ThreadsDoNotFit& e) {
        // Refused before the scan read anything: each thread fewer frees a stack, so try again
        // on as few as make up the shortfall (README: "uses fewer threads if it must").
        BakeSettings fewer = settings;
        fewer.threadsWanted = b.budget.threadsWanted;
        fewer.threads = std::min(e.threads, b.threads - 1);
        return runBake(scene, fewer);
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
    if (b.castShare) in.castShare = &*b.castShare;
    in.openSeconds = b.openSeconds, in.streamSeconds = b.streamSeconds, in.castSeconds = b.castSeconds, in.refineSeconds = b.refineSeconds;
    in.totalSeconds = total.seconds();
    nlohmann::json stats = bakeStats(in);
    if (nlohmann::json extra = b.kind->stats(); extra.is_object())
        for (auto& [key, value] : extra.items())  // merged: the pipeline's keys of an object stay (antialias)
            if (value.is_object() && stats.contains(key) && stats[key].is_object()) stats[key].update(value);
            else stats[key] = value;
    if (nlohmann::json extra = b.caster->methodStats(); !extra.is_null()) stats[settings.method] = extra;
    if (b.sharded) stats["shard"] = b.sharded->stats(), stats["shard"]["blockers_cast"] = b.p.blockersCast;
    if (b.opaqueView && !b.opaqueView->translucent().empty()) {
        const size_t collected = b.opaqueView->translucent().size() * sizeof(Triangle);
        stats["translucent"] = {{"triangles", b.opaqueView->translucent().size()}, {"bytes", collected + (b.translucent ? b.translucent->bytes() : 0)}};
        if (b.translucent) stats["translucent"]["relations_tested"] = b.translucent->tests.load(), stats["translucent"]["crossings"] = b.translucent->crossings.load();
    }
    stats["outputs_written"] = outputs.paths();  // every file of the bake, the stats themselves last
    if (!settings.statsPath.empty()) stats["outputs_written"].push_back(settings.statsPath);
    for (const std::string& warning : b.p.warnings) stats["warnings"].push_back(warning);  // after the kind's, if any
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
    // Silent, but where a cancel (the Python module's Ctrl-C) stops the write, leaving no file.
    ProgressReporter progress("write", c.kind->outputWork(), /*quiet=*/true);
    c.kind->write(OutputContext{scene, c.receivers, c.samples, c.results, output, c.firstPass, &progress});
    outputs.commit();
}

}  // namespace penumbra
