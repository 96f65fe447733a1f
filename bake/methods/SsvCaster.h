#pragma once
/// @file SsvCaster.h
/// @brief `--method ssv`: soft shadow volumes for ray tracing (Laine, Aila, Assarsson, Lehtinen &
/// Akenine-Möller 2005) with the frustum shooting of Harter, Osswald & Assarsson: per receiver,
/// the frustum from the receiver to the light's bound is shot through a kd-tree of potential
/// silhouette edges (SsvScene.h), the edges found are integrated into a depth complexity per
/// light sample relative to one reference sample, and the reference's absolute depth is counted
/// exactly by one ray. A sample is blocked where its depth is above 0.
///
/// Exactness (docs/design.md, "Soft shadow volumes"). For a receiver r, let A be the triangles
/// that hold the whole light on one side and r more than eps(r) behind them: those the rule lets
/// block r with one fixed s. For the segment from the reference sample l0 to a sample l (inside
/// the light's convex bound, so on the far side of every triangle of A), the directions from r
/// sweep a planar sector; it enters or leaves a triangle's cone exactly where it crosses an edge
/// face, i.e. where the vertices a, b of the edge lie on opposite sides of the plane (r, l0, l)
/// and l0, l on opposite sides of the edge's wedge plane (r, a, b). So
///   D(l) = D(l0) + sum over edges of A's triangles [a, b separated] ([E(l) >= 0] - [E(l0) >= 0]),
/// with E the rule's own edge value E_e = s det(l - w a, b - a, r - a), evaluated with the rule's
/// double expression and operation order, so each edge decides exactly as the rule does. Shared
/// edges whose two faces' tests cancel are left out (they are not potential silhouettes), except
/// where one face is in A and r lies in the other's epsilon band behind it: those come from the
/// band triangles near r. D(l0) counts, with the rule, the triangles of A that block l0. Triangles
/// whose plane meets the light (straddlers) are tested per sample with the rule, and the
/// reference is taken among the receiver's samples nearest the light's centre, skipping any whose
/// ray passes within 1e-9 (relative) of an edge of a triangle of A. If every candidate is that
/// close, the receiver is cast per sample against the frustum's triangles (counted). What remains
/// can differ from the rule only where two faces' edge tests do not cancel in float: a segment
/// within roundoff of a shared edge or a vertex, a tie of the rule (bake/TieClassifier.h).
///
/// Cut-outs (bake/rule/AlphaRule.h): an alpha triangle blocks only where the alpha test at the
/// hit passes, so it has no place in the depth complexity. Alpha triangles are kept apart
/// (SsvScene::alphaFaces()) and, once a receiver's opaque samples are decided, each sample still
/// open is tested with the rule and the alpha test (blocksWithAlpha(), as the reference does)
/// against the alpha triangles its frustum reaches in their own kd-tree. Translucent triangles
/// never reach the caster: the pipeline weighs them after the opaque mask (TranslucentBlockers.h).
///
/// Memory: the whole scene, unlike hpc: triangles in double (SsvFace, 128 bytes), and per light
/// the potential silhouette edges and the kd-tree (SsvScene::bytes(), in the stats).

#include "bake/rule/BlockingRule.h"
#include "stream/AlphaTable.h"
#include "bake/light/Light.h"
#include "bake/methods/SilhouetteKdTree.h"
#include "bake/cast/VisibilityMasks.h"
#include "receivers/ReceiverSet.h"
#include "stream/Triangle.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <span>

namespace penumbra {

struct SsvOptions {
    /// The paper's termination criteria: fewer than 10 triangles (edges do not count), or a box
    /// below 0.5 % of the scene box.
    KdParams tree{10, 0b110};
    int referenceCandidates = 8;  ///< samples tried as the reference before the per-sample fallback
    const AlphaTable* alpha = nullptr;  ///< the cut-outs' alpha table; null: the built-in outlines
};

/// @brief Counters of an ssv cast: the paper's numbers (kd-tree memory, edges per frustum, time
/// per receiver) and what exactness cost.
struct SsvStats {
    double buildSeconds = 0;  ///< adjacency, classification and kd-trees
    double castSeconds = 0;
    uint64_t receivers = 0;
    uint64_t faces = 0, potentialEdges = 0, straddlers = 0;
    uint64_t sceneBytes = 0;  ///< faces, edges and trees
    uint64_t treeBytes = 0, treeNodes = 0, treeLeaves = 0, treeReferences = 0;
    int treeDepth = 0;
    uint64_t frustums = 0;        ///< receiver-light pairs shot
    uint64_t edgesInFrustum = 0;  ///< potential silhouette edges found by the frustums (distinct)
    uint64_t silhouetteEdges = 0; ///< edge terms integrated (edges with an active face)
    uint64_t bandEdges = 0;       ///< of those, found through band triangles near the receiver
    uint64_t straddlersInFrustum = 0;
    uint64_t referenceTriangles = 0;  ///< triangles the reference rays tested
    uint64_t referenceRetries = 0;    ///< reference candidates passed over (ray near an edge)
    uint64_t fallbackFrustums = 0;    ///< receiver-light pairs cast per sample (every candidate too close)
    uint64_t alphaFaces = 0;          ///< cut-out triangles, tested per open sample
    uint64_t alphaInFrustum = 0;      ///< cut-out triangles the frustums reached (distinct per frustum)
    uint64_t alphaTests = 0;          ///< open samples tested against a cut-out (group culls skipped)
};

/// @brief The stats JSON's "ssv" section: the counters and the paper's per-receiver figures.
nlohmann::json ssvStatsJson(const SsvStats& stats);

/// @brief Casts every relation of @p receivers. @p progress (optional) gets receivers done.
VisibilityMasks castSsv(const LightSamples& samples, const ReceiverSet& receivers, std::span<const uint32_t> sampleSetOf,
                        std::span<const Triangle> triangles, const ReceiverEpsilon& epsilon, const SsvOptions& options = {},
                        SsvStats* stats = nullptr, const std::function<void(uint64_t)>& progress = {});

}  // namespace penumbra
