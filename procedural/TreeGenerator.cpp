#include "procedural/TreeGenerator.h"

#include "stream/AlphaTable.h"

#include "procedural/IndexedSource.h"
#include "stream/util/CheckedMath.h"
#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"
#include "stream/util/Random.h"

#include <fmt/format.h>
#include <glm/geometric.hpp>

#include <cmath>

namespace penumbra {
namespace {

constexpr double kPi = 3.14159265358979323846;
/// Per-tree triangle cap: a tree is held in memory (a forest holds `variants` of them).
constexpr uint64_t kMaxTreeTriangles = uint64_t(1) << 20;
/// Triangles of all of a forest's variants together (160 MB of them, held in memory).
constexpr uint64_t kMaxForestVariantTriangles = uint64_t(1) << 22;
constexpr uint64_t kVariantStream = 0x7472656573ull;  // "trees"

uint64_t power(uint64_t base, int exponent) {
    uint64_t r = 1;
    for (int i = 0; i < exponent; ++i) r *= base;
    return r;
}

uint64_t branchCount(const TreeParams& p) {
    uint64_t n = 0;
    for (int level = 0; level <= p.depth; ++level) n += power(uint64_t(p.branches), level);
    return n;
}

uint64_t leafCount(const TreeParams& p) { return power(uint64_t(p.branches), p.depth) * uint64_t(p.leavesPerBranch); }

/// Depth-first construction; the Rng is consumed in a fixed order, so a seed fixes the tree.
class TreeBuilder {
public:
    explicit TreeBuilder(const TreeParams& p) : p_(p), rng_(p.seed), leafFlags_(p.alphaMatte ? uint32_t(kTriangleAlphaMatte) : 0u) {
        wood_.reserve(branchCount(p) * 2 * uint64_t(p.sides));
        leaves_.reserve(leafCount(p) * 2);
    }

    std::vector<Triangle> build() {
        branch(glm::dvec3(0.0), glm::dvec3(0, 1, 0), p_.trunkLength, p_.trunkRadius, 0, rng_.uniform(0, 2 * kPi));
        wood_.insert(wood_.end(), leaves_.begin(), leaves_.end());
        return std::move(wood_);
    }

private:
    /// Signed jitter in [-jitter, jitter] x @p scale.
    double wobble(double scale) { return p_.jitter * scale * (2.0 * rng_.uniform() - 1.0); }

    void branch(const glm::dvec3& start, const glm::dvec3& dir, double length, double radius, int level, double phase) {
        // A frame around the axis; the helper is any direction not parallel to it.
        const glm::dvec3 helper = std::abs(dir.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
        const glm::dvec3 u = glm::normalize(glm::cross(dir, helper)), w = glm::cross(dir, u);
        const glm::dvec3 end = start + dir * length;
        const double tipRadius = radius * p_.radiusRatio;
        for (int k = 0; k < p_.sides; ++k) {
            auto ring = [&](const glm::dvec3& centre, double r, int j) {
                const double a = 2 * kPi * double(j % p_.sides) / double(p_.sides);
                return glm::vec3(centre + r * (std::cos(a) * u + std::sin(a) * w));
            };
            const glm::vec3 a0 = ring(start, radius, k), a1 = ring(start, radius, k + 1);
            const glm::vec3 b0 = ring(end, tipRadius, k), b1 = ring(end, tipRadius, k + 1);
            wood_.push_back(Triangle{{a0, a1, b1}, 0});
            wood_.push_back(Triangle{{a0, b1, b0}, 0});
        }
        if (level == p_.depth) {
            addLeaves(start, dir, length, u, w);
            return;
        }
        const double angle = p_.branchingAngleDeg * kPi / 180.0;
        for (int c = 0; c < p_.branches; ++c) {
            const double azimuth = phase + 2 * kPi * (c + wobble(0.5)) / p_.branches;
            const double tilt = angle * (1.0 + wobble(0.5));
            glm::dvec3 childDir = std::cos(tilt) * dir + std::sin(tilt) * (std::cos(azimuth) * u + std::sin(azimuth) * w);
            childDir = glm::normalize(childDir);
            // The first child continues from the tip; the others sprout a little lower, as on real trees.
            const double at = c == 0 ? 1.0 : 1.0 - 0.35 * p_.jitter * rng_.uniform() - 0.1;
            const double childLength = length * p_.lengthRatio * (1.0 + wobble(0.5));
            branch(start + dir * (length * at), childDir, childLength, tipRadius, level + 1, rng_.uniform(0, 2 * kPi));
        }
    }

    void addLeaves(const glm::dvec3& start, const glm::dvec3& dir, double length, const glm::dvec3& u, const glm::dvec3& w) {
        const double size = p_.leafSize;
        for (int q = 0; q < p_.leavesPerBranch; ++q) {
            const double t = 0.3 + 0.7 * (q + 0.5 + wobble(0.5)) / p_.leavesPerBranch;
            const glm::dvec3 at = start + dir * (length * t);
            const double a = rng_.uniform(0, 2 * kPi);
            // Leaves point outward, somewhat along the branch and a little up. The sideways part
            // has length 1 and the rest at most 0.8, so the direction is never parallel to `dir`.
            const glm::dvec3 d = glm::normalize(std::cos(a) * u + std::sin(a) * w + 0.5 * dir + glm::dvec3(0, 0.3, 0));
            const glm::dvec3 e = glm::normalize(glm::cross(d, dir));
            const glm::vec3 p0(at - 0.5 * size * e), p1(at + 0.5 * size * e);
            const glm::vec3 p2(at + 0.5 * size * e + size * d), p3(at - 0.5 * size * e + size * d);
            // p1, p2, p3, p0 are the canonical quad's corners (0,0) (1,0) (1,1) (0,1): u runs from the
            // stalk along d, so the outline's midrib is the leaf's.
            const bool cut = p_.alphaMatte && p_.leafCutout;
            leaves_.push_back(Triangle{{p1, p2, p3}, cut ? withAlphaId(leafFlags_, kAlphaLeafLower) : leafFlags_});
            leaves_.push_back(Triangle{{p1, p3, p0}, cut ? withAlphaId(leafFlags_, kAlphaLeafUpper) : leafFlags_});
        }
    }

    const TreeParams& p_;
    Rng rng_;
    uint32_t leafFlags_;
    std::vector<Triangle> wood_, leaves_;
};

// Trees are built on the first read, not when the source opens: the memory plan counts them
// (residentBytes()) in between, so that a budget too small for them is refused before they are
// allocated (a forest of 64 variants peaked at 177 MiB under an 80M budget).
class TreeSource final : public IndexedSource {
public:
    explicit TreeSource(const TreeParams& p) : IndexedSource("tree", treeTriangleCount(p)), p_(p) {}
    size_t read(std::span<Triangle> out) override {
        if (triangles_.empty()) triangles_ = buildTree(p_);
        return IndexedSource::read(out);
    }
    uint64_t residentBytes() const override { return treeTriangleCount(p_) * sizeof(Triangle); }

protected:
    void triangle(uint64_t index, Triangle& out) const override { out = triangles_[index]; }

private:
    TreeParams p_;
    std::vector<Triangle> triangles_;  // built by the first read()
};

class ForestSource final : public IndexedSource {
public:
    explicit ForestSource(const ForestParams& p)
        : IndexedSource("forest", p.placement.count * treeTriangleCount(p.tree)), p_(p), perTree_(treeTriangleCount(p.tree)) {}
    size_t read(std::span<Triangle> out) override {
        for (int v = int(variants_.size()); v < p_.variants && !out.empty(); ++v) {
            TreeParams variant = p_.tree;
            variant.seed = hashIndex(p_.seed, uint64_t(v), kVariantStream);
            variants_.push_back(buildTree(variant));
        }
        p_.placement.prepare();
        return IndexedSource::read(out);
    }
    uint64_t residentBytes() const override {
        return uint64_t(p_.variants) * perTree_ * sizeof(Triangle) + p_.placement.residentBytes();
    }
    std::string residentDetail() const override {
        const uint64_t bytes = uint64_t(p_.variants) * perTree_ * sizeof(Triangle);
        if (bytes < kNotableResidentBytes) return {};
        return fmt::format("forest keeps {} variants of {} triangles ({:.1f} MiB; fewer variants or smaller trees need less)",
                           p_.variants, perTree_, double(bytes) / (1 << 20));
    }

protected:
    struct Instance {
        glm::dvec3 base;
        double c, s, scale;
        uint32_t variant;
    };

    Instance instance(uint64_t tree) const {
        Rng rng(hashIndex(p_.seed, tree));
        Instance in;
        double x, z;
        randomPoint(p_.placement.area, rng, x, z);
        const double yaw = rng.uniform(0, 2 * kPi);
        in.c = std::cos(yaw), in.s = std::sin(yaw);
        in.scale = rng.uniform(p_.scale.x, p_.scale.y);
        in.variant = uint32_t(rng.next() % uint64_t(p_.variants));
        // Sunk by the trunk radius so that the trunk meets sloped ground without a gap.
        in.base = glm::dvec3(x, p_.placement.groundHeight(x, z) - p_.tree.trunkRadius * in.scale, z);
        return in;
    }

    void triangle(uint64_t index, Triangle& out) const override { fill(index, std::span<Triangle>(&out, 1)); }

    void fill(uint64_t first, std::span<Triangle> out) const override {
        uint64_t current = UINT64_MAX;
        Instance in{};
        for (size_t k = 0; k < out.size(); ++k) {
            const uint64_t tree = (first + k) / perTree_;
            if (tree != current) in = instance(tree), current = tree;
            const Triangle& local = variants_[in.variant][(first + k) % perTree_];
            for (int j = 0; j < 3; ++j) {
                const glm::dvec3 q = in.scale * glm::dvec3(local.v[j]);
                out[k].v[j] = glm::vec3(in.base + glm::dvec3(in.c * q.x + in.s * q.z, q.y, in.c * q.z - in.s * q.x));
            }
            out[k].flags = local.flags;
        }
    }

private:
    ForestParams p_;
    uint64_t perTree_;
    std::vector<std::vector<Triangle>> variants_;  // built by the first read()
};

/// Reads the keys shared by "tree" and "forest"; the caller calls finish().
TreeParams readTreeKeys(const JsonParams& j) {
    TreeParams p;
    p.depth = int(j.integer("depth", p.depth, 0, 12));
    p.branches = int(j.integer("branches", p.branches, 1, 8));
    p.branchingAngleDeg = j.number("branching_angle_deg", p.branchingAngleDeg);
    p.lengthRatio = j.number("length_ratio", p.lengthRatio);
    p.radiusRatio = j.number("radius_ratio", p.radiusRatio);
    p.trunkLength = j.number("trunk_length", p.trunkLength);
    p.trunkRadius = j.number("trunk_radius", p.trunkRadius);
    p.sides = int(j.integer("sides", p.sides, 3, 32));
    p.leavesPerBranch = int(j.integer("leaves_per_branch", p.leavesPerBranch, 0, 64));
    p.leafSize = j.number("leaf_size", p.leafSize);
    p.alphaMatte = j.boolean("alpha_matte", p.alphaMatte);
    p.leafCutout = j.boolean("leaf_cutout", p.leafCutout);
    p.jitter = j.number("jitter", p.jitter);
    p.seed = j.seed("seed", p.seed);
    return p;
}

void validateTree(const JsonParams& j, const TreeParams& p) {
    if (!(p.branchingAngleDeg >= 0 && p.branchingAngleDeg <= 180))
        fail(j.where("branching_angle_deg"), "must be in 0..180, got {}", p.branchingAngleDeg);
    if (!(p.lengthRatio > 0 && p.lengthRatio <= 2)) fail(j.where("length_ratio"), "must be in (0, 2], got {}", p.lengthRatio);
    if (!(p.radiusRatio > 0 && p.radiusRatio <= 1)) fail(j.where("radius_ratio"), "must be in (0, 1], got {}", p.radiusRatio);
    if (!(p.trunkLength > 0 && p.trunkLength <= 1e6)) fail(j.where("trunk_length"), "must be in (0, 1e6], got {}", p.trunkLength);
    if (!(p.trunkRadius > 0 && p.trunkRadius <= p.trunkLength))
        fail(j.where("trunk_radius"), "must be positive and at most trunk_length, got {}", p.trunkRadius);
    if (!(p.leafSize > 0 && p.leafSize <= 1e6)) fail(j.where("leaf_size"), "must be in (0, 1e6], got {}", p.leafSize);
    if (!(p.jitter >= 0 && p.jitter <= 1)) fail(j.where("jitter"), "must be in 0..1, got {}", p.jitter);
    if (treeTriangleCount(p) > kMaxTreeTriangles)
        fail(j.where("depth"), "a tree would have {} triangles, more than the limit of {}; lower depth, branches or leaves_per_branch",
             treeTriangleCount(p), kMaxTreeTriangles);
}

}  // namespace

uint64_t treeTriangleCount(const TreeParams& p) {
    return branchCount(p) * 2 * uint64_t(p.sides) + leafCount(p) * 2;
}

std::vector<Triangle> buildTree(const TreeParams& p) { return TreeBuilder(p).build(); }

double treeReach(const TreeParams& p) {
    // Longest possible chain of branches (each child at most 1 + jitter/2 times its ratio), plus
    // a trunk radius and a leaf's far corner (sqrt(1.25) leaf sizes from its stalk).
    double length = p.trunkLength, total = 0;
    for (int level = 0; level <= p.depth; ++level) {
        total += length;
        length *= p.lengthRatio * (1.0 + 0.5 * p.jitter);
    }
    return total + p.trunkRadius + 1.12 * p.leafSize;
}

TreeParams parseTreeParams(const SourceRequest& request) {
    JsonParams j(request.params, request.file, request.path);
    TreeParams p = readTreeKeys(j);
    j.finish();
    validateTree(j, p);
    return p;
}

ForestParams parseForestParams(const SourceRequest& request) {
    JsonParams j(request.params, request.file, request.path);
    ForestParams f;
    f.tree = readTreeKeys(j);
    f.seed = f.tree.seed;
    validateTree(j, f.tree);
    f.placement = parsePlacement(j, 100, kMaxSceneTriangles / treeTriangleCount(f.tree));
    f.variants = int(j.integer("variants", f.variants, 1, 64));
    // The variants are built and kept whole: bound their memory like one big tree's.
    checkedProduct({uint64_t(f.variants), treeTriangleCount(f.tree)}, kMaxForestVariantTriangles, j.where("variants"),
                   "triangles kept for the variants");
    f.scale = j.range("scale", f.scale);
    j.finish();
    if (!(f.scale.x > 0 && f.scale.y <= 1e3)) fail(j.where("scale"), "must lie in (0, 1000], got [{}, {}]", f.scale.x, f.scale.y);
    return f;
}

TriangleSourcePtr makeTreeSource(const TreeParams& params) { return std::make_unique<TreeSource>(params); }
TriangleSourcePtr makeForestSource(const ForestParams& params) { return std::make_unique<ForestSource>(params); }

}  // namespace penumbra
