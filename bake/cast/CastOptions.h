#pragma once
/// @file CastOptions.h
/// @brief Switches and parameters of hierarchical penumbra casting, and what a cast measures.

#include "bake/cast/HardShadowBlock.h"
#include "bake/cast/ReceiverHierarchy.h"
#include "stream/AlphaTable.h"

#include <cstdint>
#include <memory>

namespace penumbra {

/// @brief Each optimization of Laine & Aila's Figure 3 can be switched off for testing and
/// measurement; all combinations give identical masks.
struct CastOptions {
    bool umbraBits = true;     ///< A: group/full-umbra bits on nodes and receivers
    bool activePlanes = true;  ///< B: active plane sets
    bool lazyVolumes = true;   ///< C: build V_Gk and hard-shadow volumes only when needed
    bool lazyMasks = true;     ///< D: allocate masks on demand, release them in full umbra
    bool rebuild = true;       ///< rebuild the hierarchy without umbra receivers (needs A)
    bool sortBlockers = true;  ///< process blockers largest first
    /// The bucket pass drops blockers out of every light's reach (bake/ReachCull.h) instead of
    /// writing them to disk for the caster to cull; masks do not change.
    bool cullBeforeSpill = true;
    /// Sintorn et al. 2008 plane-to-bitmask tables (SampleMaskTable.h) decide most of a group's
    /// bits before the per-sample test; exact, so masks do not change. Measured faster on GRIDS
    /// and flowers: docs/performance.md, "Sample mask table".
    bool sampleTable = true;
    /// Sintorn et al. 2008: a triangle marked kTriangleClosed whose plane has the whole light
    /// strictly behind it is skipped. A segment that crosses it enters the solid and leaves it
    /// through a triangle facing the light sample, which blocks it, so masks do not change as long
    /// as no light sample lies inside a closed solid (except for ties of the blocking rule:
    /// segments that only graze the solid). The receivers for which the face that should block
    /// lies within the rule's epsilon are found before each tile and cast with every face
    /// (ClosedExemptions.h).
    bool closedCasters = true;
    /// With table rows (the light on one side of T's plane), T's group volumes V_Gk are built only
    /// once T has reached more than this many receivers of a tile past the leaf prefilter: the rows
    /// decide every group of a receiver at once, so V_Gk pay only for blockers whose penumbra
    /// holds many receivers (docs/performance.md, "Group volumes deferred"). 0 builds them for
    /// the first receiver, as Figure 3 does; `--disable defer-group-volumes`. Masks do not change.
    uint32_t groupVolumesAfter = 32;
    /// A blocker whose plane cuts the light: per receiver, the box of the light that T covers seen
    /// from it (SampleMaskTable::footprint()) clears the samples outside it before V_Gk and the
    /// exact tests (docs/performance.md, "Footprints of split blockers"). Needs the sample table;
    /// `--disable footprints`. Masks do not change.
    bool footprints = true;
    /// An alpha triangle: per receiver and group, the region of T that the group's samples hit
    /// is bounded, and where the map is opaque (or clear) all over it, the group's hits skip their
    /// alpha tests (bake/rule/AlphaBound.h; docs/performance.md, "Alpha tests by group").
    /// `--disable alpha-bounds`. Masks do not change.
    bool alphaBounds = true;
    /// A closed face (closed casters on): V_L gets one more plane that culls the receivers in
    /// front of T, which the face never blocks, instead of a test of every visited node's box
    /// (BlockerBatch.h, cutInFront(); docs/performance.md, "Closed faces' front in V_L").
    /// `--disable front-plane`. Masks do not change.
    bool frontPlane = true;
    /// --method embree: accept a hit only when the blocking rule blocks (an occlusion filter), so
    /// Embree decides like hpc but for float edge ties. Off: Embree's native answer, with the
    /// epsilon as tnear along the ray, which also blocks grazing rays the rule does not.
    bool embreeRuleFilter = true;
    /// Tests only: microseconds the last tile of a chunk waits before it counts the chunk's root
    /// culls, to widen the window in which a scheduling race there would show (0: none).
    int countDelayForTestsUs = 0;
    int sampleTableAngles = 128;   ///< angle bins of each table
    int sampleTableOffsets = 128;  ///< offset bins of each table
    double rebuildThreshold = 0.25;  ///< rebuild when this fraction of live receivers is in umbra
    HierarchyParams hierarchy;
    double epsilon = 1e-5;     ///< receiver-end epsilon, relative (BlockingRule.h)
    /// L of eps(r) = epsilon * max(|r|_inf, L): the largest |coordinate| of the first pass's
    /// receivers, set by the pipeline after the scan pass (1 until then, and in unit tests).
    double epsilonLength = 1.0;
    int groupSize = 64;        ///< light samples per group, 1..64
    SimdLevel simd = SimdLevel::Auto;  ///< instruction set of the hard-shadow tests (same bits for all)
    /// The alpha maps and ids that alpha triangles' flags name (bake/rule/AlphaRule.h); null: the
    /// built-in outlines only.
    std::shared_ptr<const AlphaTable> alphaTable;
};

/// @brief The alpha table of @p options: its own, or the built-in outlines.
inline const AlphaTable& alphaTableOf(const CastOptions& options) {
    return options.alphaTable ? *options.alphaTable : *AlphaTable::builtin();
}

/// @brief The rule's receiver epsilon for @p options.
inline ReceiverEpsilon receiverEpsilonOf(const CastOptions& options) { return {options.epsilon, options.epsilonLength}; }

/// @brief How far in front of a closed face's plane a point must lie to be culled: eps(r) at a
/// receiver whose largest |coordinate| is @p extent, plus 1e-12 (@p offset + @p extent) for the
/// rounding of every receiver's own distance, @p offset bounding |c - v0|_1 over the culled points.
/// TileCaster::inFrontOfClosed() takes it per box, cutInFront() (BlockerBatch.h) over every box.
inline double closedFrontMargin(const CastOptions& options, double extent, double offset) {
    return receiverEpsilonOf(options).at(glm::dvec3(extent)) + 1e-12 * (offset + extent);
}

/// @brief Counters and timers of one cast, summed over tiles (the paper's Table 2 columns).
struct CastStats {
    double hierarchyBuildSeconds = 0;  ///< thread-seconds, all builds and rebuilds
    /// Wall-clock seconds of the first builds of the tiles' hierarchies, before the cast starts
    /// (rebuilds happen during the cast, so castSeconds holds their wall time).
    double hierarchyBuildWallSeconds = 0;
    /// Wall-clock seconds from the first cast() to the end of flush(): tiles cast in the background
    /// while the caller reads the next chunk, so this includes the replay read.
    double castSeconds = 0;
    double replayReadSeconds = 0;  ///< of castSeconds, the caller's time reading the bucket replay
    /// Wall-clock seconds of the pass after the cast that hands every receiver's masks on to be
    /// shaded (hpc's `[shade]` phase); 0 for methods that shade each receiver as they find it.
    double shadeSeconds = 0;
    uint64_t trianglesProcessed = 0;
    uint64_t trianglesCulledAtRoot = 0;  ///< no tile root box intersected V_L
    uint64_t closedBackFaces = 0;        ///< closed-surface triangles facing away from every light
    uint64_t closedExemptReceivers = 0;  ///< receivers cast with every face (ClosedExemptions.h)
    double closedExemptSeconds = 0;      ///< wall time of the passes that found them
    uint64_t rebuilds = 0;
    uint64_t peakLiveMasks = 0;
    uint64_t peakMaskBytes = 0;
    uint64_t peakHierarchyBytes = 0;
    uint64_t receiverBytes = 0;
    uint64_t hardShadowTests = 0;
    uint64_t tableDecidedRelations = 0;  ///< open relations the sample mask table decided
    uint64_t sampleTableBytes = 0;       ///< memory of the sample mask tables
    uint64_t alphaTests = 0;             ///< hits on alpha triangles that took the alpha test
    uint64_t alphaRejected = 0;          ///< of those, hits on transparent texels (not blocked)
    uint64_t alphaGroupTests = 0;        ///< (receiver, group) pairs whose alpha test was tried at once
    uint64_t alphaGroupsDecided = 0;     ///< of those, the ones decided (no per-hit alpha test)
};

/// @brief Adds the stats of one more tile or cast pass to @p total. Tiles and passes run one
/// after another, so peaks are the largest one's, not the sum.
void addSequential(CastStats& total, const CastStats& s);

}  // namespace penumbra
