#include "bake/ScenePasses.h"

#include "bake/BakeMemory.h"
#include "bake/BakeWarnings.h"
#include "bake/WorkPlan.h"
#include "bake/cast/Caster.h"
#include "bake/cast/ReachCull.h"
#include "bake/light/SunLight.h"
#include "bake/shard/ShardRun.h"
#include "bucket/BucketPlan.h"
#include "stream/BlockCyclicSource.h"
#include "stream/PrefetchSource.h"
#include "stream/Translucency.h"
#include "stream/util/Error.h"
#include "stream/util/Memory.h"
#include "stream/util/StopRequest.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {


/// Grows the scene's bounding box and counts the casting translucent triangles (the translucent
/// pass's memory) in one visit of each triangle. Non-finite vertices never get here: every scene
/// entry is read through a FiniteSource (Scene.cpp), which names the entry.
class SceneTally {
public:
    void operator()(std::span<const Triangle> chunk) {
        for (const Triangle& t : chunk) {
            for (const glm::vec3& v : t.v) lo_ = glm::min(lo_, v), hi_ = glm::max(hi_, v);
            translucent_ += !(t.flags & kTriangleNoCast) && isTranslucentId(alphaIdOf(t.flags));
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
    uint64_t seen_ = 0;
    uint64_t translucent_ = 0;
    glm::vec3 lo_{INFINITY}, hi_{-INFINITY};
};

/// Rejects a receiver that a receiver_offset moved past the float range (the kinds check their own
/// inputs, but an offset of 1e39 along a normal makes an infinite receiver out of a finite one,
/// and the hierarchy cannot hold it).
void checkReceiversFinite(const SceneDesc& scene, const ReceiverSet& receivers) {
    for (size_t r = 0; r < receivers.size(); ++r) {
        const glm::vec3& p = receivers.position[r];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
            const bool offsets = std::any_of(scene.receiverClasses.begin(), scene.receiverClasses.end(),
                                             [](const ReceiverClass& c) { return c.offset != 0.0; });
            fail(scene.file, "receiver {} lies at a non-finite position, past the float range (about 3.4e38){}", r,
                 offsets ? ": a geometry entry's receiver_offset moves it there" : "");
        }
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

}  // namespace

void feedPass(ReceiverKind& kind, StreamPass pass, TriangleSource& source, bool streamOrder, ProgressReporter* progress) {
    std::vector<Triangle> chunk(kTriangleChunk);
    while (size_t n = source.read(chunk)) {
        kind.consume(pass, StreamChunk{std::span<const Triangle>(chunk.data(), n), streamOrder ? source.part() : kAnyGeometryEntry});
        if (progress) progress->update(n);
        throwIfStopRequested("pass over the geometry");
    }
}

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
        SceneTally tally;
        ClosedSolidScan solids(p.samples);
        const bool scanPass = kind.wantsPass(StreamPass::Scan);
        std::vector<Triangle> chunk(kTriangleChunk);
        while (size_t n = source->read(chunk)) {
            std::span<const Triangle> part(chunk.data(), n);
            tally(part);
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
        // Nothing left to skip: this also spares hpc its pass that finds the receivers closed
        // casters must not skip for (ClosedExemptions.h).
        if (p.openedSolids.kept == 0) p.options.closedCasters = false;
        p.options.epsilonLength = epsilonLength(p.receivers, tally.box());
        p.translucentScanned = tally.translucent();
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
    p.warnings = bakeWarnings(scene.receivers, p.receivers, p.lights, scene.file);
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
    if (share && p.options.closedCasters) {
        // The receivers closed casters must not skip for are found from every closed face
        // (ClosedExemptions.h), and a by-blockers shard reads only its share of them.
        p.options.closedCasters = false;
        if (!settings.quiet) printNote("closed casters are off in a by-blockers shard, which does not see every closed face");
    }
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

}  // namespace penumbra
