#include "bake/methods/SilhouetteKdTree.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>

namespace penumbra {

namespace {

/// A node still to be built (the build is iterative).
struct Pending {
    KdBox box;
    int depth = 0;
    uint32_t node = 0;
    std::vector<uint32_t> items;  ///< indices into the build's item array
};

}  // namespace

void SilhouetteKdTree::build(std::vector<KdItem> items, const KdParams& params) {
    nodes_.clear(), leafStart_.clear(), refs_.clear(), depth_ = 0;
    root_ = KdBox{};
    for (const KdItem& item : items)
        if (!item.box.empty()) root_.add(item.box.lo), root_.add(item.box.hi);
    if (root_.empty()) root_.add(glm::dvec3(0.0));
    const glm::dvec3 rootSize = root_.hi - root_.lo;
    const double minSide = params.minBoxFraction * std::max({rootSize.x, rootSize.y, rootSize.z});

    std::vector<Pending> stack(1);
    stack[0].box = root_;
    stack[0].items.reserve(items.size());
    for (uint32_t i = 0; i < items.size(); ++i)
        if (!items[i].box.empty()) stack[0].items.push_back(i);
    nodes_.push_back(Node{});
    uint64_t listed = stack[0].items.size();  // references emitted and pending

    auto makeLeaf = [&](Pending& p) {
        Node& node = nodes_[p.node];
        node.axis = 3;
        node.child = uint32_t(leafStart_.size() / (kKdKinds + 1));
        // Stable by kind, then by id: the order of a leaf's lists does not depend on the build.
        std::sort(p.items.begin(), p.items.end(), [&](uint32_t a, uint32_t b) {
            return items[a].kind != items[b].kind ? items[a].kind < items[b].kind : items[a].id < items[b].id;
        });
        size_t k = 0;
        for (int kind = 0; kind <= kKdKinds; ++kind) {
            leafStart_.push_back(uint32_t(refs_.size()));
            if (kind == kKdKinds) break;
            for (; k < p.items.size() && items[p.items[k]].kind == kind; ++k) refs_.push_back(items[p.items[k]].id);
        }
        depth_ = std::max(depth_, p.depth);
    };

    while (!stack.empty()) {
        Pending p = std::move(stack.back());
        stack.pop_back();
        const glm::dvec3 size = p.box.hi - p.box.lo;
        const int axis = size.x >= size.y && size.x >= size.z ? 0 : (size.y >= size.z ? 1 : 2);
        int counted = 0;
        for (size_t i = 0; i < p.items.size() && counted < params.leafItems; ++i) counted += params.countedKinds >> items[p.items[i]].kind & 1;
        if (counted < params.leafItems || size[axis] <= minSide || p.depth >= params.maxDepth) {
            makeLeaf(p);
            continue;
        }
        const double split = 0.5 * (p.box.lo[axis] + p.box.hi[axis]);
        Pending left, right;
        left.box = right.box = p.box;
        left.box.hi[axis] = right.box.lo[axis] = split;
        // Counted first, so that each list is allocated once at its size: grown by doubling,
        // the lists of a scene of coincident edges held twice the references the plan counts.
        size_t toLeft = 0, toRight = 0;
        for (uint32_t i : p.items) toLeft += items[i].box.lo[axis] <= split, toRight += items[i].box.hi[axis] >= split;
        left.items.reserve(toLeft), right.items.reserve(toRight);
        for (uint32_t i : p.items) {
            if (items[i].box.lo[axis] <= split) left.items.push_back(i);
            if (items[i].box.hi[axis] >= split) right.items.push_back(i);
        }
        // A split that lists every item on both sides only multiplies references.
        if (left.items.size() == p.items.size() && right.items.size() == p.items.size()) {
            makeLeaf(p);
            continue;
        }
        const uint64_t more = left.items.size() + right.items.size() - p.items.size();
        if (params.maxBytes && (listed + more) * sizeof(uint32_t) + (nodes_.size() + 2) * kKdNodeBytes > params.maxBytes) {
            makeLeaf(p);
            continue;
        }
        listed += more;
        const uint32_t child = uint32_t(nodes_.size());
        nodes_[p.node].axis = uint8_t(axis), nodes_[p.node].split = split, nodes_[p.node].child = child;
        nodes_.push_back(Node{}), nodes_.push_back(Node{});
        left.node = child, right.node = child + 1;
        left.depth = right.depth = p.depth + 1;
        std::vector<uint32_t>().swap(p.items);
        stack.push_back(std::move(right));
        stack.push_back(std::move(left));
    }
    nodes_.shrink_to_fit(), leafStart_.shrink_to_fit(), refs_.shrink_to_fit();
}

template <class Test>
void SilhouetteKdTree::visit(Test&& test, const std::function<void(uint32_t leaf)>& visit) const {
    struct Entry {
        uint32_t node;
        KdBox box;
    };
    std::array<Entry, 128> stack;
    int top = 0;
    if (test(root_)) stack[top++] = {0, root_};
    while (top > 0) {
        const Entry e = stack[--top];
        const Node& node = nodes_[e.node];
        if (node.axis == 3) {
            visit(node.child);
            continue;
        }
        Entry left{node.child, e.box}, right{node.child + 1, e.box};
        left.box.hi[node.axis] = right.box.lo[node.axis] = node.split;
        if (test(right.box)) stack[top++] = right;
        if (test(left.box)) stack[top++] = left;
    }
}

void SilhouetteKdTree::visitCone(std::span<const KdPlane> planes, const std::function<void(uint32_t)>& f) const {
    visit(
        [&](const KdBox& b) {
            for (const KdPlane& p : planes) {
                // The box corner farthest along the normal (Assarsson & Möller's p-vertex).
                const glm::dvec3 corner(p.n.x > 0 ? b.hi.x : b.lo.x, p.n.y > 0 ? b.hi.y : b.lo.y, p.n.z > 0 ? b.hi.z : b.lo.z);
                if (glm::dot(p.n, corner - p.apex) < -p.margin) return false;
            }
            return true;
        },
        f);
}

void SilhouetteKdTree::visitPoint(const glm::dvec3& q, double margin, const std::function<void(uint32_t)>& f) const {
    visit(
        [&](const KdBox& b) {
            for (int a = 0; a < 3; ++a)
                if (q[a] < b.lo[a] - margin || q[a] > b.hi[a] + margin) return false;
            return true;
        },
        f);
}

void SilhouetteKdTree::visitSegment(const glm::dvec3& o, const glm::dvec3& d, double tmax, double margin,
                                    const std::function<void(uint32_t)>& f) const {
    visit(
        [&](const KdBox& b) {
            double t0 = 0, t1 = tmax;
            for (int a = 0; a < 3; ++a) {
                const double lo = b.lo[a] - margin, hi = b.hi[a] + margin;
                if (d[a] == 0.0) {
                    if (o[a] < lo || o[a] > hi) return false;
                    continue;
                }
                double ta = (lo - o[a]) / d[a], tb = (hi - o[a]) / d[a];
                if (ta > tb) std::swap(ta, tb);
                t0 = std::max(t0, ta), t1 = std::min(t1, tb);
                if (t0 > t1) return false;
            }
            return true;
        },
        f);
}

}  // namespace penumbra
