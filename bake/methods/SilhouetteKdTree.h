#pragma once
/// @file SilhouetteKdTree.h
/// @brief The kd-tree of Harter, Osswald & Assarsson ("Soft Shadow Volumes for Ray Tracing with
/// Frustum Shooting"), over the items soft shadow volumes look up: potential silhouette edges and
/// triangles.
///
/// Splitting follows the paper's final choice: a box is split in half on its longest axis (the
/// authors found the surface area heuristic 5-10 % faster to render but too slow to build for
/// large scenes). An item whose box straddles the split plane is listed in both children. A box
/// becomes a leaf when it holds fewer than `leafItems` items of the counted kinds (the paper: ten
/// triangles), when its
/// longest side is below `minBoxFraction` of the root's (the paper: 0.5 %), at `maxDepth`, when
/// a split would list every item in both children, or when it would take the tree past `maxBytes`. Only leaves hold items (the paper's version
/// 0.6, its best memory/time compromise); each leaf lists its items by kind, so a query that
/// wants only edges never touches triangles.
///
/// Queries visit leaves: those a convex cone (the receiver-to-light frustum) reaches, those that
/// contain a point, and those a segment or ray passes through. Boxes are tested with a margin, so
/// a query never misses an item whose box it touches within roundoff. The same item may be
/// reported by several leaves: callers deduplicate.

#include <glm/common.hpp>
#include <glm/vec3.hpp>

#include <cmath>

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

namespace penumbra {

/// @brief A closed axis-aligned box in double precision.
struct KdBox {
    glm::dvec3 lo{INFINITY}, hi{-INFINITY};
    void add(const glm::dvec3& p) { lo = glm::min(lo, p), hi = glm::max(hi, p); }
    bool empty() const { return !(lo.x <= hi.x); }
};

/// @brief One item to index: its box, an id chosen by the caller, and its kind (< kKdKinds).
struct KdItem {
    KdBox box;
    uint32_t id = 0;
    uint8_t kind = 0;
};

inline constexpr int kKdKinds = 3;

/// @brief A half-space through a point: inside where dot(n, p - apex) >= -margin.
struct KdPlane {
    glm::dvec3 n;
    glm::dvec3 apex;
    double margin = 0;
};

/// @brief Build parameters (the paper's termination criteria and a depth guard).
struct KdParams {
    int leafItems = 10;         ///< a box with fewer counted items is a leaf
    uint8_t countedKinds = 0xff;  ///< bit k: items of kind k count towards leafItems
    double minBoxFraction = 0.005;
    int maxDepth = 40;
    /// Most bytes the tree may hold, with the item lists of the boxes still to split (0: no
    /// limit). A split that would pass it makes a leaf instead: items whose boxes overlap without
    /// separating (many triangles on a few points) were listed in ever more leaves, and the tree
    /// went past the memory plan threefold. Queries stay exact, only slower there.
    uint64_t maxBytes = 0;
};

/// Bytes a tree node costs in the byte limit: the node, and a leaf's share of its offsets.
inline constexpr uint64_t kKdNodeBytes = 24;

class SilhouetteKdTree {
public:
    /// @brief Builds the tree over @p items (consumed). Deterministic for the same items.
    void build(std::vector<KdItem> items, const KdParams& params = {});

    /// @brief Calls @p visit with every leaf whose box is not wholly outside one of @p planes.
    void visitCone(std::span<const KdPlane> planes, const std::function<void(uint32_t leaf)>& visit) const;
    /// @brief Calls @p visit with every leaf whose box, grown by @p margin, contains @p p.
    void visitPoint(const glm::dvec3& p, double margin, const std::function<void(uint32_t leaf)>& visit) const;
    /// @brief Calls @p visit with every leaf whose box, grown by @p margin, meets the segment
    /// origin + t * direction, t in [0, tmax] (tmax may be infinite: a ray).
    void visitSegment(const glm::dvec3& origin, const glm::dvec3& direction, double tmax, double margin,
                      const std::function<void(uint32_t leaf)>& visit) const;

    /// The ids of the items of @p kind listed in @p leaf.
    std::span<const uint32_t> items(uint32_t leaf, int kind) const {
        const uint32_t* first = refs_.data() + leafStart_[size_t(leaf) * (kKdKinds + 1) + kind];
        return {first, first + (leafStart_[size_t(leaf) * (kKdKinds + 1) + kind + 1] - leafStart_[size_t(leaf) * (kKdKinds + 1) + kind])};
    }

    const KdBox& bounds() const { return root_; }
    uint64_t nodes() const { return nodes_.size(); }
    uint64_t leaves() const { return leafStart_.size() / (kKdKinds + 1); }
    uint64_t references() const { return refs_.size(); }
    int depth() const { return depth_; }
    /// Bytes held by the tree: nodes, leaf offsets and item references.
    uint64_t bytes() const {
        return nodes_.capacity() * sizeof(Node) + leafStart_.capacity() * sizeof(uint32_t) + refs_.capacity() * sizeof(uint32_t);
    }

private:
    struct Node {
        double split = 0;
        uint32_t child = 0;  ///< inner: index of the left child (the right one follows); leaf: leaf index
        uint8_t axis = 3;    ///< 0..2 for inner nodes, 3 for a leaf
    };

    template <class Test>
    void visit(Test&& test, const std::function<void(uint32_t leaf)>& visit) const;

    std::vector<Node> nodes_;
    std::vector<uint32_t> leafStart_;  ///< per leaf kKdKinds + 1 offsets into refs_
    std::vector<uint32_t> refs_;
    KdBox root_;
    int depth_ = 0;
};

}  // namespace penumbra
