#include "Compare.h"

#include "bake/BlockingRule.h"
#include "bake/Scene.h"
#include "stream/Error.h"
#include "stream/Npy.h"

#include <algorithm>
#include <bit>
#include <cstring>
#include <filesystem>
#include <memory>
#include <numeric>

namespace penumbra {
namespace {

/// Receivers compared per step: dumps of millions of receivers are read in pieces of this many
/// rows, so the comparison holds a few MB whatever the dump size.
constexpr uint64_t kRowsPerStep = 1 << 16;

struct Dump {
    std::string dir;
    NpyRowReader receivers, masks;  ///< read a block of rows at a time
    NpyArray samples;               ///< small (sets x samples x 3): read whole
    explicit Dump(const std::string& d)
        : dir(d), receivers(path("receivers.npy")), masks(path("masks.npy")), samples(readNpy(path("samples.npy"))) {
        const NpyHeader &rh = receivers.header(), &mh = masks.header();
        if (rh.dtype != "<f4" || rh.shape.size() != 2 || rh.shape[1] != 7) fail(path("receivers.npy"), "expected float32 N x 7");
        if (samples.dtype != "<f4" || samples.shape.size() != 3 || samples.shape[2] != 3)
            fail(path("samples.npy"), "expected float32 S x K x 3");
        const uint64_t n = rh.shape[0], k = samples.shape[1];
        if (mh.dtype != "<u8" || mh.shape.size() != 2 || mh.shape[0] != n || mh.shape[1] != (k + 63) / 64)
            fail(path("masks.npy"), "expected uint64 {} x {} to match receivers.npy and samples.npy", n, (k + 63) / 64);
    }
    std::string path(const char* name) const { return (std::filesystem::path(dir) / name).string(); }
};

/// The scene's blockers with a median-split bounding-volume hierarchy over their boxes, so a
/// mismatch is classified against the triangles near its segment rather than all of them.
///
/// A mismatch can only be explained by a triangle that one of the two methods found on the
/// segment (up to roundoff), so such a triangle's box always meets the segment: the tie test is
/// applied to the triangles whose box, grown by the tie tolerance, the segment meets. (isTie()
/// alone would also accept a far-away triangle whose infinite plane happens to pass through the
/// receiver, e.g. any floor triangle for every floor receiver.)
class TieClassifier {
public:
    TieClassifier(const SceneDesc& scene, double tolerance) : epsilon_(scene.options.epsilon), tolerance_(tolerance) {
        TriangleSourcePtr source = openSceneGeometry(scene);
        std::vector<Triangle> chunk(kTriangleChunk);
        while (size_t n = source->read(chunk))
            for (size_t i = 0; i < n; ++i)
                if (BlockerTriangle bt = BlockerTriangle::from(chunk[i]); bt.valid) triangles_.push_back(bt);
        if (triangles_.empty()) return;
        std::vector<uint32_t> order(triangles_.size());
        std::iota(order.begin(), order.end(), 0u);
        nodes_.reserve(2 * triangles_.size() / kLeaf + 1);
        build(order, 0, uint32_t(order.size()));
        std::vector<BlockerTriangle> sorted;
        sorted.reserve(order.size());
        for (uint32_t i : order) sorted.push_back(triangles_[i]);
        triangles_.swap(sorted);
    }

    /// True when some triangle near the segment from @p recv to @p light makes the relation a tie.
    bool tie(const glm::dvec3& light, const glm::dvec3& recv) const {
        if (nodes_.empty()) return false;
        const double margin = tolerance_ * std::max({1.0, glm::length(recv), glm::length(light)}) +
                              2.0 * receiverEpsilon(recv, epsilon_);
        uint32_t stack[64];
        int top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const Node& node = nodes_[stack[--top]];
            if (!segmentMeetsBox(recv, light, node, margin)) continue;
            if (node.count > 0) {
                for (uint32_t i = node.first; i < node.first + node.count; ++i)
                    if (isTie(light, recv, triangles_[i], epsilon_, tolerance_)) return true;
            } else {
                stack[top++] = node.first;      // left child
                stack[top++] = node.first + 1;  // right child
            }
        }
        return false;
    }

private:
    static constexpr uint32_t kLeaf = 4;
    struct Node {
        glm::dvec3 lo, hi;
        uint32_t first = 0;  ///< leaf: first triangle; inner: index of the left child (right follows)
        uint32_t count = 0;  ///< triangles in a leaf; 0 for an inner node
    };

    static bool segmentMeetsBox(const glm::dvec3& a, const glm::dvec3& b, const Node& box, double margin) {
        double t0 = 0.0, t1 = 1.0;
        for (int axis = 0; axis < 3; ++axis) {
            const double lo = box.lo[axis] - margin, hi = box.hi[axis] + margin, d = b[axis] - a[axis];
            if (d == 0.0) {
                if (a[axis] < lo || a[axis] > hi) return false;
                continue;
            }
            double ta = (lo - a[axis]) / d, tb = (hi - a[axis]) / d;
            if (ta > tb) std::swap(ta, tb);
            t0 = std::max(t0, ta), t1 = std::min(t1, tb);
            if (t0 > t1) return false;
        }
        return true;
    }

    /// Builds the subtree over order[first, last) and returns its node index. Children of a node
    /// are stored next to each other, so the stack depth stays at the tree depth (~log2 n).
    uint32_t build(std::vector<uint32_t>& order, uint32_t first, uint32_t last) {
        const uint32_t index = uint32_t(nodes_.size());
        nodes_.push_back({});
        buildInto(order, index, first, last);
        return index;
    }

    void buildInto(std::vector<uint32_t>& order, uint32_t index, uint32_t first, uint32_t last) {
        Node node;
        node.lo = glm::dvec3(INFINITY), node.hi = glm::dvec3(-INFINITY);
        glm::dvec3 clo(INFINITY), chi(-INFINITY);
        for (uint32_t i = first; i < last; ++i) {
            const BlockerTriangle& t = triangles_[order[i]];
            for (const glm::dvec3& v : t.v) node.lo = glm::min(node.lo, v), node.hi = glm::max(node.hi, v);
            const glm::dvec3 c = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
            clo = glm::min(clo, c), chi = glm::max(chi, c);
        }
        if (last - first <= kLeaf) {
            node.first = first, node.count = last - first;
            nodes_[index] = node;
            return;
        }
        const glm::dvec3 extent = chi - clo;
        const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
        const uint32_t mid = first + (last - first) / 2;
        std::nth_element(order.begin() + first, order.begin() + mid, order.begin() + last, [&](uint32_t a, uint32_t b) {
            const BlockerTriangle &ta = triangles_[a], &tb = triangles_[b];
            return ta.v[0][axis] + ta.v[1][axis] + ta.v[2][axis] < tb.v[0][axis] + tb.v[1][axis] + tb.v[2][axis];
        });
        const uint32_t left = uint32_t(nodes_.size());
        nodes_.push_back({});
        nodes_.push_back({});
        node.first = left;
        nodes_[index] = node;
        buildInto(order, left, first, mid);
        buildInto(order, left + 1, mid, last);
    }

    std::vector<BlockerTriangle> triangles_;
    std::vector<Node> nodes_;
    double epsilon_, tolerance_;
};

}  // namespace

CompareResult compareDumps(const std::string& dirA, const std::string& dirB, const std::string& scenePath) {
    Dump a(dirA), b(dirB);
    if (a.receivers.header().shape != b.receivers.header().shape)
        fail(dirB, "receivers.npy differs from {}: the dumps are not of the same receivers", dirA);
    if (a.samples.shape != b.samples.shape || a.samples.data != b.samples.data)
        fail(dirB, "samples.npy differs from {}: the dumps are not of the same light samples", dirA);

    CompareResult r;
    r.receivers = a.receivers.header().shape[0];
    r.samples = a.samples.shape[1];
    r.relations = r.receivers * r.samples;
    const uint64_t words = (r.samples + 63) / 64;
    auto smp = reinterpret_cast<const float*>(a.samples.data.data());

    std::unique_ptr<TieClassifier> classifier;
    if (!scenePath.empty()) {
        classifier = std::make_unique<TieClassifier>(loadScene(scenePath), 1e-4);
        r.classified = true;
    }

    std::vector<float> rec, recOther;
    std::vector<uint64_t> ma, mb;
    for (uint64_t first = 0; first < r.receivers; first += kRowsPerStep) {
        const uint64_t rows = std::min(kRowsPerStep, r.receivers - first);
        a.receivers.next(rows, rec), b.receivers.next(rows, recOther);
        if (std::memcmp(rec.data(), recOther.data(), rec.size() * sizeof(float)) != 0)
            fail(dirB, "receivers.npy differs from {}: the dumps are not of the same receivers", dirA);
        a.masks.next(rows, ma), b.masks.next(rows, mb);
        for (uint64_t i = 0; i < rows; ++i)
            for (uint64_t w = 0; w < words; ++w) {
                const uint64_t x = ma[i * words + w], y = mb[i * words + w];
                r.blockedA += std::popcount(x), r.blockedB += std::popcount(y);
                r.onlyA += std::popcount(x & ~y), r.onlyB += std::popcount(y & ~x);
                if (!classifier) continue;
                for (uint64_t diff = x ^ y; diff; diff &= diff - 1) {
                    const uint64_t k = w * 64 + uint64_t(std::countr_zero(diff));
                    const float* p = rec.data() + i * 7;
                    const float* s = smp + (uint64_t(p[6]) * r.samples + k) * 3;
                    r.ties += classifier->tie(glm::dvec3(s[0], s[1], s[2]), glm::dvec3(p[0], p[1], p[2]));
                }
            }
    }
    return r;
}

}  // namespace penumbra
