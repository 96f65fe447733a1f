#pragma once
/// @file SsvScene.h
/// @brief What `--method ssv` holds in memory: the scene's triangles in double precision with
/// their adjacency, and per light the potential silhouette edges, the triangles whose plane meets
/// the light, and the SilhouetteKdTree over both (Harter, Osswald & Assarsson 2005).
///
/// - Adjacency: vertices are matched by their exact float positions (corners sorted by position,
///   -0 and +0 alike), edges by their two vertices. An edge with two faces is shared; one with
///   one face, or three and more (non-manifold), is a boundary edge of each of its faces.
/// - Per light, every face gets the side of its plane that holds the whole light (the rule's
///   s = sign(N . (l - w v0)) is then the same for every sample), decided at the light bound's
///   vertices with a margin of 1e-9 of the coordinates, far above the roundoff of any sample in
///   the bound's hull. A face with the light on both sides, or too close to its plane, is a
///   *straddler*: the caster tests it per sample with the rule.
/// - A *potential silhouette edge* (the paper's Figure 2 test) is a boundary edge, an edge of a
///   straddler, or a shared edge whose faces' rule edge tests do not cancel: with the light on
///   the same side of both faces' orientation along the edge (o = s * direction of the edge in the
///   face; the tests cancel when o1 = -o2). Only those are in the tree. For a receiver r, a shared
///   edge whose faces would cancel can still bound the set of triangles that block r when one face
///   blocks and r lies within the rule's epsilon band behind the other; the caster finds those
///   through the band triangles near r. A triangle's box is grown by the band radius: the
///   farthest from r such an edge can be and still be seen against the light,
///   eps_max * max|l - w r| / h, with h the distance of the light's bound from the face's plane.
/// - Kd-tree items: kind 0 potential silhouette edges (id into SsvLight::edges), kind 1
///   straddlers and kind 2 the other triangles (id = face index), both for the reference ray.
/// - Cut-out triangles (an alpha id, bake/rule/AlphaRule.h) block only where the alpha test at
///   the hit passes, so they bound no opaque depth complexity: they are not faces (no edges, no
///   adjacency) but a list of their own with one light-independent kd-tree over their boxes
///   (kind kSsvTriangleItem), which the caster tests per open sample after the opaque pass.

#include "bake/rule/BlockingRule.h"
#include "bake/light/Light.h"
#include "bake/methods/SilhouetteKdTree.h"
#include "stream/Triangle.h"

#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

inline constexpr uint32_t kNoFace = ~0u;
enum SsvItemKind : uint8_t { kSsvEdgeItem = 0, kSsvStraddlerItem = 1, kSsvTriangleItem = 2 };

/// @brief A valid triangle (BlockingRule.h) and its neighbours across each edge.
struct SsvFace {
    BlockerTriangle t;
    uint32_t neighbor[3] = {kNoFace, kNoFace, kNoFace};  ///< across edge e = (v[e], v[e+1])
    uint8_t neighborEdge[3] = {0, 0, 0};                  ///< that edge's index in the neighbour
};

/// @brief A potential silhouette edge: up to two faces and the edge's index in each.
struct SsvEdge {
    uint32_t face[2] = {kNoFace, kNoFace};
    uint8_t edge[2] = {0, 0};
};

/// @brief Per light: faces' sides, potential silhouette edges and the kd-tree.
struct SsvLight {
    std::vector<int8_t> side;        ///< per face: +1 / -1, the side holding the light; 0 straddler
    std::vector<uint8_t> potential;  ///< per face: bit e set when edge e is a potential silhouette
    std::vector<SsvEdge> edges;
    SilhouetteKdTree tree;
    uint64_t straddlers = 0;
    double bandRadiusMax = 0;        ///< largest band radius of a non-straddler
    uint64_t bytes() const;
};

/// @brief Counters of the preprocessing, for the stats.
struct SsvSceneStats {
    uint64_t faces = 0, alphaFaces = 0, vertices = 0, sharedEdges = 0, boundaryEdges = 0;
    double buildSeconds = 0;
};

class SsvScene {
public:
    /// @param triangles the scene (invalid triangles are dropped: they block nothing)
    /// @param receiverBox box of every receiver, for the band radius
    SsvScene(std::span<const Triangle> triangles, const LightSamples& samples, const ReceiverEpsilon& epsilon,
             const KdBox& receiverBox, const KdParams& params = {});

    const std::vector<SsvFace>& faces() const { return faces_; }
    const SsvLight& light(int l) const { return lights_[size_t(l)]; }
    /// Cut-out triangles (alpha id != 0) and the kd-tree over their boxes.
    const std::vector<BlockerTriangle>& alphaFaces() const { return alpha_; }
    const SilhouetteKdTree& alphaTree() const { return alphaTree_; }
    const SsvSceneStats& stats() const { return stats_; }
    /// Bytes held: faces, cut-outs, per-light arrays and trees.
    uint64_t bytes() const;
    /// @brief What the memory plan reserves for @p triangles triangles and @p lights lights: 128
    /// bytes of face; while a light's tree is built, its items (at most three edges and the
    /// triangle, 56 bytes each); and per light its sides, edges and the kd-tree, whose build stops
    /// splitting at kTreeBytesPerTriangle (GRIDS needs 335 bytes a triangle, flowers 150,
    /// sponza-like 50; a fan of 60,000 triangles on 6 points needed 1,240 before the limit).
    /// The tree being built holds up to three times that at its peak: its reference and node
    /// arrays grow by doubling while the pending lists are still alive (massif, 60,000 triangles
    /// on 5 points: 56 MB of build for a 23 MB tree; a budget named without it was exceeded by 20 %).
    static uint64_t plannedBytes(uint64_t triangles, int lights) {
        return triangles * (128 + 4 * sizeof(KdItem) + kLightBytesPerTriangle * uint64_t(lights) +
                            kTreeBytesPerTriangle * (uint64_t(lights) + kTreeBuildPeak - 1));
    }
    /// The peak of a tree's build, in final trees of kTreeBytesPerTriangle (see plannedBytes()).
    static constexpr uint64_t kTreeBuildPeak = 3;
    static constexpr uint64_t kTreeBytesPerTriangle = 384;
    /// Per light and triangle: its side and potential-edge bits, and up to three edges.
    static constexpr uint64_t kLightBytesPerTriangle = 2 + 3 * sizeof(SsvEdge);

private:
    void findAdjacency();
    void classify(int light, const LightSamples& samples, const ReceiverEpsilon& epsilon, const KdBox& receiverBox,
                  const KdParams& params);

    std::vector<SsvFace> faces_;
    std::vector<SsvLight> lights_;
    std::vector<BlockerTriangle> alpha_;
    SilhouetteKdTree alphaTree_;
    SsvSceneStats stats_;
    double sceneSize_ = 1;
};

}  // namespace penumbra
