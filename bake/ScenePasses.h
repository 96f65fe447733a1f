#pragma once
/// @file ScenePasses.h
/// @brief The bake's passes over the scene before casting: the scan (receivers, area histogram,
/// vertex checks, closed solids) and the bucket pass (blockers spilled largest first), and the
/// helper that feeds a receiver kind one more pass over the blockers.

#include "bake/Pipeline.h"
#include "bake/cast/ClosedSolids.h"
#include "bake/kinds/ReceiverKind.h"
#include "bake/light/Light.h"
#include "bucket/BucketFiles.h"
#include "bucket/BucketPlan.h"
#include "receivers/ReceiverSet.h"
#include "stream/TriangleSource.h"
#include "stream/util/Progress.h"

#include <functional>
#include <string>
#include <vector>

namespace penumbra {

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

/// Every chunk of @p source to the kind's @p pass, with the chunk's geometry entry when the
/// source is in stream order (@p streamOrder).
void feedPass(ReceiverKind& kind, StreamPass pass, TriangleSource& source, bool streamOrder,
              ProgressReporter* progress = nullptr);

/// Pass 1 over the stream: camera receivers are rasterized (or points loaded) while the area
/// histogram is built and every vertex is checked. Pass 2 streams the blockers into area buckets
/// on disk; casting then replays the buckets, largest first, once per memory tile. So the source
/// is read at most twice and no pass holds more than a bounded window of triangles.
/// @param afterScan called once the scan has found the receivers, before the bucket pass writes
///        anything: the exact memory check.
/// @throw InputError for non-finite vertices or receivers, a full disk, a memory plan refused.
Prepared prepare(const SceneDesc& scene, const BakeSettings& settings, ReceiverKind& kind, TriangleSourcePtr geometry,
                 const std::function<void(const Prepared&, uint64_t triangles)>& afterScan, double& streamSeconds,
                 BucketStats& buckets);

}  // namespace penumbra
