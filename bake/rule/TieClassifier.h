#pragma once
/// @file TieClassifier.h
/// @brief Decides whether a mismatch between two bakes is a *tie* of the blocking rule: a relation
/// whose decision could flip under the float roundoff of its inputs, so that an independent,
/// correct implementation may legitimately decide it the other way.
///
/// For one relation (sample (l, w), receiver r) the classifier evaluates the rule itself against
/// every scene triangle near the segment or ray, and for each triangle the rule's four
/// quantities, each against its threshold with a tolerance of a few float ulps of the
/// quantities involved (never a fixed fraction of the scene):
///  - SampleInPlane: s = N̂ . (l - w v0) against 0 (a point sample in T's plane, or a sun direction
///    parallel to it). Tolerance k u (|l|_inf + |T|_inf) for a point, k u |l| for a direction.
///  - Band: the receiver's distance behind T's plane against eps(r). Tolerance
///    k u |T - r|_inf + 4 u max(|r|_inf, |T|_inf).
///  - Edge: how far the segment passes inside (positive) or outside an edge, as the angle seen
///    from the receiver (the distance between the segment's line and the edge's line divided by
///    the distance from r to the point c where the segment meets T's plane). Tolerance
///    (k u |{a, b} - r|_inf + 4 u max(|r|, |T|)_inf) / |c - r| + k u + 4 u |l|_inf / |l - r| for a
///    point sample, without the last term for a direction.
/// with u = 2^-24 (float) and k = ulps (default 32). The main term is T's distance from r, since
/// a float ray tracer works relative to the ray's origin, so ties stay as narrow far from the
/// origin as near it; the 4 ulps of the coordinates cover its box tests, which subtract the
/// origin at the world's scale. (With k ulps of the coordinates, a small mesh at 1e4 had every
/// edge within tolerance, and a dump with every mask zeroed compared as all ties.)
/// A triangle's decision is *robust* when it
/// blocks with every quantity beyond its tolerance, or fails one quantity beyond its tolerance.
/// A relation the rule blocks is a tie only when no blocking triangle is robust; a relation the
/// rule does not block is a tie only when some triangle is not robust. Everything else is a real
/// mismatch, and the verdict names the triangle that decides it.
///
///  - Alpha: for an alpha triangle the rule blocks geometrically, the alpha test at the hit
///    (bake/rule/AlphaRule.h); fragile when the hit is within roundoff of a texel edge or outline,
///    or, for a geometry entry's "max_distance", when the hit's distance from the receiver is
///    within 2^-40 (relative to the coordinates) of the limit.
/// Triangles of "cast_shadows": false entries (kTriangleNoCast) block nothing here either.
/// Memory: the scene's valid triangles (as BlockerTriangle, 112 bytes each) and a BVH over them.
/// This is a checking tool for scenes that fit in memory, not a part of the bake.

#include "bake/rule/BlockingRule.h"
#include "stream/AlphaTable.h"

#include <memory>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

/// The rule's quantity that a verdict is about.
enum class RuleQuantity { None, SampleInPlane, Band, Edge, Alpha };

/// @brief The classifier's answer for one relation.
struct RelationVerdict {
    bool ruleBlocks = false;  ///< the rule's own decision over the scene's triangles
    bool tie = false;         ///< the decision could flip within the tolerances
    /// The deciding quantity: for a tie, the one within tolerance (of the fragile triangle); for a
    /// robust block, the blocker's quantity nearest its threshold; None for a robust non-block.
    RuleQuantity quantity = RuleQuantity::None;
    uint64_t triangle = 0;    ///< index of the triangle in the scene stream (when quantity != None)
    int edge = -1;            ///< for Edge
    double value = 0, threshold = 0, tolerance = 0;  ///< in the quantity's unit (world units or radians)

    /// @brief One line: "tie: edge 2 of triangle 17 passes 3.1e-07 rad inside (threshold 0,
    /// tolerance 9.5e-07 rad)", or "real: triangle 17 blocks (band 0.012 > eps 1e-05 ...)".
    std::string describe() const;
};

class TieClassifier {
public:
    static constexpr double kDefaultUlps = 32;

    /// @param triangles the scene's triangles in stream order (invalid ones are kept out but
    /// keep their index)
    /// @param alpha the alpha maps alpha triangles name (null: the built-in outlines). A hit on an
    /// alpha triangle is fragile also when it lies within roundoff of a texel edge or an outline.
    TieClassifier(std::span<const Triangle> triangles, const ReceiverEpsilon& epsilon, double ulps = kDefaultUlps,
                  std::shared_ptr<const AlphaTable> alpha = nullptr);

    /// @brief Classifies the relation of sample (@p l, @p w) and receiver @p r.
    RelationVerdict classify(const glm::dvec3& l, double w, const glm::dvec3& r) const;

    size_t triangles() const { return triangles_.size(); }

private:
    struct Node {
        glm::dvec3 lo, hi;
        uint32_t first = 0;  ///< leaf: first triangle; inner: index of the left child (right follows)
        uint32_t count = 0;  ///< triangles in a leaf; 0 for an inner node
    };
    struct Judged;  ///< one triangle's quantities against the relation

    Judged judge(uint32_t index, const glm::dvec3& l, double w, const glm::dvec3& r) const;
    void build(std::vector<uint32_t>& order, uint32_t index, uint32_t first, uint32_t last);

    std::vector<BlockerTriangle> triangles_;
    std::vector<uint64_t> streamIndex_;
    std::vector<double> maxAbs_;  ///< per triangle: largest |coordinate|
    std::vector<Node> nodes_;
    ReceiverEpsilon epsilon_;
    double ulps_;
    double sceneMaxAbs_ = 0;  ///< of every triangle, for the BVH's distance margin
    std::shared_ptr<const AlphaTable> alpha_;
};

}  // namespace penumbra
