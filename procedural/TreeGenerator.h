#pragma once
/// @file TreeGenerator.h
/// @brief "tree" and "forest": recursively branching trunks of tapered cylinders with quad leaves.
///
/// A tree is small (thousands of triangles), so its triangles are built once, in the constructor,
/// in the tree's own frame (trunk base at the origin, growing along +y). A forest builds a few
/// such variants and streams N instances of them, each placed, turned and scaled by a hash of
/// (seed, tree index). All trees share one topology, so triangle i belongs to tree i / T for a
/// fixed T and nothing per tree is stored.

#include "procedural/Placement.h"
#include "stream/SourceRegistry.h"

#include <glm/vec2.hpp>

#include <vector>

namespace penumbra {

struct TreeParams {
    int depth = 4;                  ///< levels of branching below the trunk (0: a bare trunk)
    int branches = 3;               ///< children per branch, 1..8
    double branchingAngleDeg = 35;  ///< angle between a child and its parent, degrees
    double lengthRatio = 0.7;       ///< child length / parent length
    double radiusRatio = 0.6;       ///< radius at a branch's tip (and its children's base) / at its base
    double trunkLength = 1.5;       ///< world units
    double trunkRadius = 0.08;      ///< radius at the trunk's base, world units
    int sides = 6;                  ///< sides of each tapered cylinder, 3..32
    int leavesPerBranch = 8;        ///< leaf quads on each outermost branch
    double leafSize = 0.15;         ///< side of a leaf quad, world units
    bool alphaMatte = true;         ///< flag leaf triangles kTriangleAlphaMatte
    /// Leaves are cut-outs with the built-in leaf outline (stream/AlphaTable.h, kAlphaLeafLower),
    /// not solid quads; needs alphaMatte.
    bool leafCutout = true;
    double jitter = 0.25;           ///< randomness of angles and lengths, 0 (regular) .. 1
    uint64_t seed = 1;
};

/// Triangles in one tree with these parameters (the same for every seed).
uint64_t treeTriangleCount(const TreeParams& p);

/// @brief Builds one tree in its own frame: trunk base at the origin, trunk along +y. Branch
/// triangles come first (2 x sides per branch, depth-first order), then the leaves (2 each).
std::vector<Triangle> buildTree(const TreeParams& p);

/// Radius of a sphere around the origin holding every vertex of any tree with these parameters.
double treeReach(const TreeParams& p);

struct ForestParams {
    TreeParams tree;               ///< shared topology; each variant re-seeds it
    Placement placement;           ///< count, area, ground
    int variants = 8;              ///< distinct trees built; instances pick one by hash, 1..64
    glm::dvec2 scale{0.7, 1.3};    ///< uniform scale range of each instance
    uint64_t seed = 1;
};

/// @brief Parse a "tree" / "forest" entry. @throw InputError naming the bad key.
TreeParams parseTreeParams(const SourceRequest& request);
ForestParams parseForestParams(const SourceRequest& request);

TriangleSourcePtr makeTreeSource(const TreeParams& params);
TriangleSourcePtr makeForestSource(const ForestParams& params);

}  // namespace penumbra
