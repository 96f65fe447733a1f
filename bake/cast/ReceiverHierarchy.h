#pragma once
/// @file ReceiverHierarchy.h
/// @brief The bounding volume hierarchy over the live receivers of one tile, with the umbra bits
/// of optimization A on every node and every receiver (Laine & Aila 2005, Sections 3.2-3.3).

#include "bake/cast/MaskPool.h"

#include <glm/vec3.hpp>

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

struct HierarchyParams {
    int leafSize = 16;           ///< split while a node holds more receivers than this
    int medianSplitAbove = 1024; ///< spatial-median splits above this many receivers, SAH below
};

/// @brief One receiver entering a hierarchy.
struct ReceiverInput {
    glm::dvec3 position;
    double epsilon;      ///< receiver-end epsilon (BlockingRule.h)
    uint32_t id;         ///< index in the bake's ReceiverSet
    uint32_t sampleSet;
};

/// @brief Live receivers of a tile, stored in hierarchy (leaf) order, the BVH over them, and the
/// umbra bits. Receivers that reach full umbra stay until the next rebuild, which drops them into
/// `retired` (their result is "every sample blocked").
class ReceiverHierarchy {
public:
    struct Node {
        glm::vec3 lo, hi;
        uint32_t first;  ///< leaf: first receiver; internal: left child (right child is first + 1)
        uint32_t count;  ///< receivers in a leaf; 0 for an internal node
        bool leaf() const { return count != 0; }
    };

    /// @param groups number of light-sample groups (umbra bits per node and receiver)
    ReceiverHierarchy(HierarchyParams params, int groups) : params_(params), groups_(groups), words_((groups + 63) / 64) {}

    /// Replaces the contents with @p receivers and builds the hierarchy.
    void build(std::vector<ReceiverInput> receivers);
    /// Drops full-umbra receivers (releasing nothing: their masks were released on entering umbra)
    /// and rebuilds over the rest.
    void rebuild();

    int groups() const { return groups_; }
    int umbraWords() const { return words_; }
    size_t liveCount() const { return position.size(); }

    // Receivers, in hierarchy order.
    std::vector<glm::dvec3> position;
    std::vector<double> epsilon;
    std::vector<uint32_t> id, sampleSet;
    std::vector<uint32_t> mask;          ///< MaskPool slot or MaskPool::kNone
    std::vector<uint8_t> fullUmbra;
    std::vector<uint64_t> groupUmbra;    ///< umbraWords() per receiver
    size_t umbraCount = 0;               ///< live receivers with fullUmbra set

    // Nodes; node 0 is the root (absent when there are no live receivers).
    std::vector<Node> nodes;
    std::vector<uint8_t> nodeFullUmbra;
    std::vector<uint64_t> nodeGroupUmbra;  ///< umbraWords() per node

    std::vector<uint32_t> retired;  ///< ids of receivers dropped in full umbra

    bool groupUmbraBit(const uint64_t* bits, uint32_t k) const { return (bits[k >> 6] >> (k & 63)) & 1u; }
    /// @brief Recomputes node @p i's umbra bits from its receivers (a leaf) or its two children:
    /// a group is in umbra at a node when it is at every receiver below it (lines 50-54 and
    /// 77-80 of Laine & Aila's Figure 3). Inline: the traversal calls it for every node it
    /// leaves, and out of line it cost 3-5 % of the cast on grids under the 4x light.
    void foldUmbra(uint32_t i);
    /// Bytes of the hierarchy proper (nodes and node bits), the "hierarchy mem" column.
    size_t hierarchyBytes() const { return nodes.capacity() * sizeof(Node) + nodeFullUmbra.capacity() + nodeGroupUmbra.capacity() * 8; }
    /// Bytes of the per-receiver arrays, the "samples mem" column.
    size_t receiverBytes() const;

private:
    /// A receiver while the nodes are built: its position beside its index, so that the splits
    /// read and move one contiguous array instead of following an order into the positions.
    struct BuildItem {
        glm::dvec3 position;
        uint32_t index;
    };
    void buildNodes();
    /// Binned SAH over the three axes: the axis and bin of the cheapest split (axis -1: none).
    static void sahSplit(std::span<const BuildItem> items, const glm::dvec3& lo, const glm::dvec3& ext, int& bestAxis,
                         int& bestBin);
    uint32_t buildRange(uint32_t node, uint32_t begin, uint32_t end, std::vector<BuildItem>& items);

    HierarchyParams params_;
    int groups_, words_;
};

inline void ReceiverHierarchy::foldUmbra(uint32_t i) {
    const Node& node = nodes[i];
    uint64_t* bits = &nodeGroupUmbra[size_t(i) * words_];
    if (node.leaf()) {
        // Word by word into a register: ANDing into bits[w] per receiver made every step wait on
        // the store before it (the arrays may alias, as far as the compiler knows).
        uint8_t full = 1;
        for (uint32_t r = node.first; r < node.first + node.count; ++r) full &= fullUmbra[r];
        for (int w = 0; w < words_; ++w) {
            uint64_t all = ~0ull;
            for (uint32_t r = node.first; r < node.first + node.count; ++r) all &= groupUmbra[size_t(r) * words_ + w];
            bits[w] = all;
        }
        nodeFullUmbra[i] = full;
        return;
    }
    nodeFullUmbra[i] = nodeFullUmbra[node.first] & nodeFullUmbra[node.first + 1];
    const uint64_t* left = &nodeGroupUmbra[size_t(node.first) * words_];
    const uint64_t* right = &nodeGroupUmbra[size_t(node.first + 1) * words_];
    for (int w = 0; w < words_; ++w) bits[w] = left[w] & right[w];
}

}  // namespace penumbra
