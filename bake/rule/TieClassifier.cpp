#include "bake/rule/TieClassifier.h"

#include "stream/Translucency.h"

#include "bake/rule/AlphaRule.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace penumbra {
namespace {

constexpr double kFloatUlp = 0x1p-24;
constexpr uint32_t kLeaf = 4;
/// Float ulps of the coordinates' magnitude in every tolerance, besides the ulps of T's distance
/// from r (the constructor's ulps).
constexpr double kWorldUlps = 4;

double maxAbs(const glm::dvec3& p) { return std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}); }

/// One quantity of the rule for one triangle: its value, threshold and tolerance, and whether the
/// rule's test passes. margin() is how far beyond roundoff the decision is.
struct Quantity {
    RuleQuantity kind = RuleQuantity::None;
    int edge = -1;
    double value = 0, threshold = 0, tolerance = 0;
    bool passes = false;
    double margin() const { return std::abs(value - threshold); }
    bool fragile() const { return !(margin() > tolerance); }
    double ratio() const { return tolerance > 0 ? margin() / tolerance : INFINITY; }
};

/// Does the segment from @p a along @p d for t in [0, t1] meet the box grown by @p margin?
bool meetsBox(const glm::dvec3& a, const glm::dvec3& d, double t1, const glm::dvec3& lo, const glm::dvec3& hi,
              double margin) {
    double t0 = 0.0;
    for (int axis = 0; axis < 3; ++axis) {
        const double l = lo[axis] - margin, h = hi[axis] + margin;
        if (d[axis] == 0.0) {
            if (a[axis] < l || a[axis] > h) return false;
            continue;
        }
        double ta = (l - a[axis]) / d[axis], tb = (h - a[axis]) / d[axis];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta), t1 = std::min(t1, tb);
        if (t0 > t1) return false;
    }
    return true;
}

}  // namespace

/// One triangle against one relation: the rule's decision, and the quantity that makes it robust
/// or not.
struct TieClassifier::Judged {
    bool blocks = false;
    bool robust = true;
    Quantity decisive;  ///< a blocker's quantity nearest its threshold, or the one that is fragile
};

std::string RelationVerdict::describe() const {
    const char* unit = quantity == RuleQuantity::Edge ? " rad" : "";
    std::string what;
    switch (quantity) {
        case RuleQuantity::None:
            return tie ? "tie" : (ruleBlocks ? "real: blocked" : "real: no triangle is within roundoff of blocking");
        case RuleQuantity::SampleInPlane:
            what = fmt::format("the sample's side of triangle {}'s plane is {:.3g}", triangle, value);
            break;
        case RuleQuantity::Band:
            what = fmt::format("the receiver lies {:.3g} behind triangle {}'s plane (eps {:.3g})", value, triangle, threshold);
            break;
        case RuleQuantity::Edge:
            what = fmt::format("the segment passes {:.3g} rad {} edge {} of triangle {}", std::abs(value),
                               value >= 0 ? "inside" : "outside", edge, triangle);
            break;
        case RuleQuantity::Alpha:
            what = fmt::format("the hit on triangle {} is {}{}", triangle, value > threshold ? "opaque" : "transparent",
                               tolerance > 0 ? " within roundoff of a texel edge or outline" : "");
            break;
    }
    return fmt::format("{}: {} (threshold {:.3g}{}, tolerance {:.3g}{}{})", tie ? "tie" : "real", what, threshold, unit,
                       tolerance, unit, ruleBlocks ? "; the rule blocks" : "; the rule does not block");
}

TieClassifier::TieClassifier(std::span<const Triangle> triangles, const ReceiverEpsilon& epsilon, double ulps,
                             std::shared_ptr<const AlphaTable> alpha)
    : epsilon_(epsilon), ulps_(ulps), alpha_(alpha ? std::move(alpha) : AlphaTable::builtin()) {
    for (size_t i = 0; i < triangles.size(); ++i) {
        const BlockerTriangle bt = BlockerTriangle::from(triangles[i]);
        // "cast_shadows": false and translucent triangles (stream/Translucency.h) block nothing.
        if (!bt.valid || (triangles[i].flags & kTriangleNoCast) || isTranslucentId(bt.alpha)) continue;
        triangles_.push_back(bt);
        streamIndex_.push_back(i);
        maxAbs_.push_back(std::max({maxAbs(bt.v[0]), maxAbs(bt.v[1]), maxAbs(bt.v[2])}));
        sceneMaxAbs_ = std::max(sceneMaxAbs_, maxAbs_.back());
    }
    if (triangles_.empty()) return;
    std::vector<uint32_t> order(triangles_.size());
    std::iota(order.begin(), order.end(), 0u);
    nodes_.reserve(2 * triangles_.size() / kLeaf + 1);
    nodes_.push_back({});
    build(order, 0, 0, uint32_t(order.size()));
    auto permute = [&](auto& v) {
        std::remove_reference_t<decltype(v)> sorted;
        sorted.reserve(order.size());
        for (uint32_t i : order) sorted.push_back(v[i]);
        v.swap(sorted);
    };
    permute(triangles_), permute(streamIndex_), permute(maxAbs_);
}

void TieClassifier::build(std::vector<uint32_t>& order, uint32_t index, uint32_t first, uint32_t last) {
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
    build(order, left, first, mid);
    build(order, left + 1, mid, last);
}

TieClassifier::Judged TieClassifier::judge(uint32_t index, const glm::dvec3& l, double w, const glm::dvec3& r) const {
    const BlockerTriangle& t = triangles_[index];
    const double uf = kFloatUlp * ulps_, mT = maxAbs_[index], lAbs = maxAbs(l), rAbs = maxAbs(r);
    Judged out;

    Quantity side{RuleQuantity::SampleInPlane};
    const double sl = t.side(l, w);
    side.value = sl, side.tolerance = uf * (w != 0.0 ? lAbs + mT : lAbs);
    side.passes = sl > 0.0 || sl < 0.0;

    const double dist = distanceBehind(t, r), eps = epsilon_.at(r);
    const glm::dvec3 span = l - w * r;  // the segment (or the ray's direction)
    const double spanLength = glm::length(span);
    // The direction's roundoff as an angle: k ulps of its own, and for a point sample, the world
    // ulps of l over the segment's length (a float implementation subtracting l - r).
    const double directionTolerance = uf + (w != 0.0 ? kFloatUlp * kWorldUlps * lAbs / spanLength : 0.0);
    const double floorDistance = kFloatUlp * std::max(rAbs, mT);
    // Where the segment's line meets T's plane, as a distance from r (infinite when parallel).
    const double along = std::abs(glm::dot(t.plane.n, span));
    const double toHit = std::max(along > 0.0 ? std::abs(dist) * spanLength / along : INFINITY, floorDistance);
    // The scale of T's roundoff as an independent test sees it: its vertices relative to r. A
    // float ray tracer works relative to the ray's origin (r), so its error near T grows with T's
    // distance from r, not with the coordinates' magnitude: a scene far from the origin keeps
    // ties as narrow as at the origin (with |T| instead, every edge of a small mesh at 1e4 was
    // a tie, and compare --scene passed a dump with every mask zeroed).
    const double local = std::max({maxAbs(t.v[0] - r), maxAbs(t.v[1] - r), maxAbs(t.v[2] - r)});
    // Plus a few ulps of the coordinates themselves: a float ray tracer's box tests subtract
    // the origin times the reciprocal direction (Embree's org_rdir), whose error is that of the
    // world position (a far sweep scene had Embree miss a hit 9 local tolerances inside an edge).
    const double world = kFloatUlp * kWorldUlps * std::max(rAbs, mT);

    // The rule's quantities for edge orientation s (the sample's side, or its opposite when the
    // sample is within roundoff of T's plane). An edge's value E = s det(span, b - a, r - a) is
    // the signed distance between the segment's line and the edge's line times |span x (b - a)|;
    // divided by the distance from r to the point where the segment meets T's plane, it is the
    // angle seen from r.
    auto quantities = [&](double s, Quantity q[4]) {
        const HardShadowVolume h = makeHardShadowVolume(l, w, t);
        q[0] = {RuleQuantity::Band, -1, -s * dist, eps, uf * local + world, -s * dist > eps};
        for (int e = 0; e < 3; ++e) {
            const glm::dvec3& a = t.v[e];
            const glm::dvec3& b = t.v[(e + 1) % 3];
            const glm::dvec3 n = h.side != 0.0 && s == -h.side ? h.edge[e] : s * glm::cross(l - w * a, b - a);
            const double value = glm::dot(n, r - a);
            const double skew = glm::length(glm::cross(span, b - a));
            const double angle = skew > 0.0 && std::isfinite(toHit) ? value / skew / toHit : 0.0;
            const double tol = (uf * std::max(maxAbs(a - r), maxAbs(b - r)) + world) / toHit + directionTolerance;
            q[1 + e] = {RuleQuantity::Edge, e, angle, 0.0, tol, value >= 0.0};
        }
    };
    auto nearest = [](const Quantity* q, int n, bool failingOnly) {
        const Quantity* best = nullptr;
        for (int i = 0; i < n; ++i)
            if ((!failingOnly || !q[i].passes) && (!best || q[i].ratio() < best->ratio())) best = &q[i];
        return best;
    };

    Quantity q[4];
    if (side.passes) {
        quantities(sl > 0.0 ? 1.0 : -1.0, q);
        out.blocks = q[0].passes && q[1].passes && q[2].passes && q[3].passes;
    }
    if (out.blocks) {  // robust when every quantity is beyond roundoff
        const Quantity* worst = nearest(q, 4, false);
        out.decisive = side.ratio() < worst->ratio() ? side : *worst;
        out.robust = !out.decisive.fragile();
        if (t.alpha) {
            const AlphaLookup a = alphaAtHit(*alpha_, makeHardShadowVolume(l, w, t), t, r);
            if (a.tie || !a.opaque) out.decisive = {RuleQuantity::Alpha, -1, a.opaque ? 1.0 : 0.0, 0.5, a.tie ? 1.0 : 0.0, a.opaque};
            out.blocks = a.opaque;
            out.robust = out.robust && !a.tie;
        }
        return out;
    }
    // Not blocking: could roundoff make T block? Only if every failing quantity is within
    // tolerance, for the sample's side or, when that side is itself fragile, the other one.
    out.robust = true;
    for (double s : {1.0, -1.0}) {
        if (!side.fragile() && s != (sl > 0.0 ? 1.0 : -1.0)) continue;
        quantities(s, q);
        bool couldBlock = true;
        for (const Quantity& x : q) couldBlock = couldBlock && (x.passes || x.fragile());
        if (!couldBlock) continue;
        out.robust = false;
        const Quantity* failing = nearest(q, 4, true);
        out.decisive = failing ? *failing : side;
        return out;
    }
    return out;
}

RelationVerdict TieClassifier::classify(const glm::dvec3& l, double w, const glm::dvec3& r) const {
    RelationVerdict verdict;
    if (nodes_.empty()) return verdict;
    const glm::dvec3 d = l - w * r;
    const double t1 = w != 0.0 ? 1.0 : INFINITY;
    const double reach = std::max({sceneMaxAbs_, maxAbs(r), w != 0.0 ? maxAbs(l) : 0.0});
    const double margin = 4.0 * kFloatUlp * ulps_ * reach + 2.0 * epsilon_.at(r);
    bool anyBlocker = false, fragileBlockerFound = false;
    Judged firstFragileBlocker, fragileNonBlocker;
    bool fragileNonBlockerFound = false;
    uint32_t fragileBlockerIndex = 0, fragileNonBlockerIndex = 0;
    uint32_t stack[64];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& node = nodes_[stack[--top]];
        if (!meetsBox(r, d, t1, node.lo, node.hi, margin)) continue;
        if (node.count == 0) {
            stack[top++] = node.first;
            stack[top++] = node.first + 1;
            continue;
        }
        for (uint32_t i = node.first; i < node.first + node.count; ++i) {
            const Judged j = judge(i, l, w, r);
            if (j.blocks && j.robust) {  // one robust blocker decides the relation
                verdict.ruleBlocks = true, verdict.tie = false;
                verdict.quantity = j.decisive.kind, verdict.edge = j.decisive.edge;
                verdict.triangle = streamIndex_[i];
                verdict.value = j.decisive.value, verdict.threshold = j.decisive.threshold;
                verdict.tolerance = j.decisive.tolerance;
                return verdict;
            }
            anyBlocker = anyBlocker || j.blocks;
            if (j.blocks && !fragileBlockerFound) fragileBlockerFound = true, firstFragileBlocker = j, fragileBlockerIndex = i;
            if (!j.blocks && !j.robust && !fragileNonBlockerFound)
                fragileNonBlockerFound = true, fragileNonBlocker = j, fragileNonBlockerIndex = i;
        }
    }
    verdict.ruleBlocks = anyBlocker;
    const Judged* decisive = anyBlocker ? &firstFragileBlocker : (fragileNonBlockerFound ? &fragileNonBlocker : nullptr);
    if (!decisive) return verdict;  // not blocked, and no triangle is within roundoff of blocking
    verdict.tie = true;
    verdict.quantity = decisive->decisive.kind, verdict.edge = decisive->decisive.edge;
    verdict.triangle = streamIndex_[anyBlocker ? fragileBlockerIndex : fragileNonBlockerIndex];
    verdict.value = decisive->decisive.value, verdict.threshold = decisive->decisive.threshold;
    verdict.tolerance = decisive->decisive.tolerance;
    return verdict;
}

}  // namespace penumbra
