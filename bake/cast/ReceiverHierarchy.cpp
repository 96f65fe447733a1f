#include "bake/cast/ReceiverHierarchy.h"

#include "stream/Triangle.h"

#include <glm/common.hpp>

#include <algorithm>
#include <array>
#include <limits>

namespace penumbra {
namespace {

constexpr int kSahBins = 32;

double halfArea(const glm::dvec3& lo, const glm::dvec3& hi) {
    glm::dvec3 e = glm::max(hi - lo, glm::dvec3(0.0));
    return e.x * e.y + e.y * e.z + e.z * e.x;
}

template <typename T>
void permute(std::vector<T>& v, const std::vector<uint32_t>& order, size_t stride = 1) {
    std::vector<T> out(order.size() * stride);
    for (size_t i = 0; i < order.size(); ++i)
        std::copy_n(v.begin() + order[i] * stride, stride, out.begin() + i * stride);
    v.swap(out);
}

}  // namespace

void ReceiverHierarchy::sahSplit(std::span<const BuildItem> items, const glm::dvec3& lo, const glm::dvec3& ext, int& bestAxis,
                                 int& bestBin) {
    const uint32_t n = uint32_t(items.size());
    double bestCost = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        if (!(ext[a] > 0.0)) continue;
        std::array<uint32_t, kSahBins> count{};
        std::array<glm::dvec3, kSahBins> blo, bhi;
        blo.fill(glm::dvec3(INFINITY)), bhi.fill(glm::dvec3(-INFINITY));
        const double scale = kSahBins / ext[a];
        for (const BuildItem& item : items) {
            const glm::dvec3& p = item.position;
            const int b = std::min(kSahBins - 1, int((p[a] - lo[a]) * scale));
            ++count[b];
            blo[b] = glm::min(blo[b], p), bhi[b] = glm::max(bhi[b], p);
        }
        std::array<double, kSahBins> rightCost{};
        glm::dvec3 rlo(INFINITY), rhi(-INFINITY);
        uint32_t rn = 0;
        for (int b = kSahBins - 1; b > 0; --b) {
            rn += count[b], rlo = glm::min(rlo, blo[b]), rhi = glm::max(rhi, bhi[b]);
            rightCost[b] = rn ? halfArea(rlo, rhi) * rn : 0.0;
        }
        glm::dvec3 llo(INFINITY), lhi(-INFINITY);
        uint32_t ln = 0;
        for (int b = 0; b + 1 < kSahBins; ++b) {
            ln += count[b], llo = glm::min(llo, blo[b]), lhi = glm::max(lhi, bhi[b]);
            if (ln == 0 || ln == n) continue;
            double cost = halfArea(llo, lhi) * ln + rightCost[b + 1];
            if (cost < bestCost) bestCost = cost, bestAxis = a, bestBin = b;
        }
    }
}

size_t ReceiverHierarchy::receiverBytes() const {
    return position.capacity() * sizeof(glm::dvec3) + epsilon.capacity() * sizeof(double) +
           (id.capacity() + sampleSet.capacity() + mask.capacity()) * sizeof(uint32_t) + fullUmbra.capacity() +
           groupUmbra.capacity() * sizeof(uint64_t);
}

void ReceiverHierarchy::build(std::vector<ReceiverInput> receivers) {
    size_t n = receivers.size();
    position.resize(n), epsilon.resize(n), id.resize(n), sampleSet.resize(n);
    for (size_t i = 0; i < n; ++i) {
        position[i] = receivers[i].position;
        epsilon[i] = receivers[i].epsilon;
        id[i] = receivers[i].id;
        sampleSet[i] = receivers[i].sampleSet;
    }
    std::vector<ReceiverInput>().swap(receivers);  // freed before buildNodes() allocates its items
    mask.assign(n, MaskPool::kNone);
    fullUmbra.assign(n, 0);
    groupUmbra.assign(n * words_, 0);
    umbraCount = 0;
    buildNodes();
}

void ReceiverHierarchy::rebuild() {
    std::vector<uint32_t> keep;
    keep.reserve(position.size() - umbraCount);
    for (uint32_t i = 0; i < position.size(); ++i) {
        if (fullUmbra[i]) retired.push_back(id[i]);
        else keep.push_back(i);
    }
    permute(position, keep), permute(epsilon, keep), permute(id, keep), permute(sampleSet, keep);
    permute(mask, keep), permute(fullUmbra, keep), permute(groupUmbra, keep, words_);
    umbraCount = 0;
    // Release capacity so "peak hierarchy memory" reflects the shrinking problem.
    position.shrink_to_fit(), epsilon.shrink_to_fit(), id.shrink_to_fit(), sampleSet.shrink_to_fit();
    mask.shrink_to_fit(), fullUmbra.shrink_to_fit(), groupUmbra.shrink_to_fit();
    buildNodes();
}

void ReceiverHierarchy::buildNodes() {
    nodes.clear();
    size_t n = position.size();
    if (n == 0) {
        nodes.shrink_to_fit();
        nodeFullUmbra.clear(), nodeGroupUmbra.clear();
        return;
    }
    // The splits partition the items (32 bytes each) in place, where an order of indices made
    // every pass read the positions at random (6 % of the build at 2560x1920). The build's
    // inputs are gone by now and the items are freed before the arrays are permuted, so the peak
    // (items and order, 36 bytes a receiver) stays within the memory plan's build allowance.
    std::vector<uint32_t> order(n);
    {
        std::vector<BuildItem> items(n);
        for (uint32_t i = 0; i < n; ++i) items[i] = {position[i], i};
        nodes.reserve(2 * (n / std::max(1, params_.leafSize / 2)) + 1);
        nodes.push_back({});
        buildRange(0, 0, uint32_t(n), items);
        for (uint32_t i = 0; i < n; ++i) order[i] = items[i].index, position[i] = items[i].position;  // positions: in place
    }
    nodes.shrink_to_fit();

    permute(epsilon, order), permute(id, order), permute(sampleSet, order);
    permute(mask, order), permute(fullUmbra, order), permute(groupUmbra, order, words_);

    // Surviving receivers may carry group-umbra bits: fold them up so nodes start consistent.
    nodeFullUmbra.assign(nodes.size(), 0);
    nodeGroupUmbra.assign(nodes.size() * words_, 0);
    for (size_t i = nodes.size(); i-- > 0;) foldUmbra(uint32_t(i));  // children always follow their parent
}

uint32_t ReceiverHierarchy::buildRange(uint32_t node, uint32_t begin, uint32_t end, std::vector<BuildItem>& items) {
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (uint32_t i = begin; i < end; ++i) lo = glm::min(lo, items[i].position), hi = glm::max(hi, items[i].position);
    // Float boxes rounded outward so they still contain the double positions.
    glm::vec3 flo = roundToFloat(lo, true), fhi = roundToFloat(hi, false);
    nodes[node].lo = flo, nodes[node].hi = fhi;
    uint32_t n = end - begin;
    if (n <= uint32_t(std::max(1, params_.leafSize))) {
        nodes[node].first = begin, nodes[node].count = n;
        return node;
    }

    glm::dvec3 ext = hi - lo;
    int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    uint32_t mid = begin;
    if (ext[axis] > 0.0 && n > uint32_t(params_.medianSplitAbove)) {
        double split = lo[axis] + 0.5 * ext[axis];  // spatial median: halve the box
        mid = uint32_t(std::partition(items.begin() + begin, items.begin() + end,
                                      [&](const BuildItem& i) { return i.position[axis] < split; }) - items.begin());
    } else if (ext[axis] > 0.0) {  // binned SAH over all three axes
        int bestAxis = -1, bestBin = 0;
        sahSplit(std::span<const BuildItem>(items).subspan(begin, n), lo, ext, bestAxis, bestBin);
        if (bestAxis >= 0) {
            double scale = kSahBins / ext[bestAxis];
            mid = uint32_t(std::partition(items.begin() + begin, items.begin() + end, [&](const BuildItem& i) {
                               return std::min(kSahBins - 1, int((i.position[bestAxis] - lo[bestAxis]) * scale)) <= bestBin;
                           }) - items.begin());
        }
    }
    if (mid == begin || mid == end) {  // coincident points or a failed split: halve by count
        mid = begin + n / 2;
        std::nth_element(items.begin() + begin, items.begin() + mid, items.begin() + end, [&](const BuildItem& a, const BuildItem& b) {
            return a.position[axis] < b.position[axis] || (a.position[axis] == b.position[axis] && a.index < b.index);
        });
    }
    uint32_t left = uint32_t(nodes.size());
    nodes.push_back({}), nodes.push_back({});
    nodes[node].first = left, nodes[node].count = 0;
    buildRange(left, begin, mid, items);
    buildRange(left + 1, mid, end, items);
    return node;
}

}  // namespace penumbra
