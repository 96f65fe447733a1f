#include "stream/AlphaTable.h"

#include "stream/util/Error.h"
#include "stream/Translucency.h"
#include "stream/Triangle.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

/// Outline values within this of 0 are ties: the inputs are O(1) texture coordinates.
constexpr double kOutlineTie = 1e-9;

/// Wraps texel index @p i into [0, n) (n >= 1).
int64_t wrapIndex(int64_t i, int64_t n, AlphaWrap wrap) {
    switch (wrap) {
        case AlphaWrap::Clamp: return i < 0 ? 0 : (i >= n ? n - 1 : i);
        case AlphaWrap::Mirror: {
            int64_t m = i % (2 * n);
            if (m < 0) m += 2 * n;
            return m < n ? m : 2 * n - 1 - m;
        }
        case AlphaWrap::Repeat: break;
    }
    int64_t m = i % n;
    return m < 0 ? m + n : m;
}

/// Texel coordinate @p x: its texel index and whether it lies within roundoff of a texel edge.
int64_t texel(double x, bool& tie) {
    const double f = std::floor(x);
    const double frac = x - f;
    const double tolerance = 0x1p-40 * std::max(1.0, std::abs(x));
    tie = tie || frac < tolerance || 1.0 - frac < tolerance;
    return int64_t(f);
}

AlphaLookup outline(double f) { return {f > 0.0, std::abs(f) < kOutlineTie}; }

/// An interval [lo, hi] of one texture coordinate over a region.
struct Span {
    double lo = INFINITY, hi = -INFINITY;
    void add(double x) { lo = std::min(lo, x), hi = std::max(hi, x); }
    void widen(double by) { lo -= by, hi += by; }
    bool contains(double x) const { return lo <= x && x <= hi; }
    /// Bounds of x^2 over the span.
    double minSquare() const { return contains(0.0) ? 0.0 : std::min(lo * lo, hi * hi); }
    double maxSquare() const { return std::max(lo * lo, hi * hi); }
};

/// The verdict of an outline whose value over the region lies in [fMin, fMax] (computed with
/// rounding far below kOutlineTie for the coordinates verdictOver() lets through).
AlphaVerdict outlineVerdict(double fMin, double fMax) {
    if (fMin > kOutlineTie) return AlphaVerdict::Opaque;
    if (fMax < -kOutlineTie) return AlphaVerdict::Clear;
    return AlphaVerdict::Mixed;
}

/// |2 x - 1| over a span: its bounds.
double maxAbsCentred(const Span& s) { return std::max(std::abs(2.0 * s.lo - 1.0), std::abs(2.0 * s.hi - 1.0)); }
double minAbsCentred(const Span& s) {
    return s.contains(0.5) ? 0.0 : std::min(std::abs(2.0 * s.lo - 1.0), std::abs(2.0 * s.hi - 1.0));
}

AlphaVerdict leafVerdict(const Span& u, const Span& v) {
    auto g = [](double x) { return 4.0 * x * (1.0 - x); };  // concave: its minimum at an end
    const double gMin = std::min(g(u.lo), g(u.hi)), gMax = g(std::clamp(0.5, u.lo, u.hi));
    return outlineVerdict(gMin - maxAbsCentred(v), gMax - minAbsCentred(v));
}

AlphaVerdict petalVerdict(const Span& u, const Span& v) {
    const Span x{2.0 * u.lo - 1.0, 2.0 * u.hi - 1.0}, y{2.0 * v.lo - 1.0, 2.0 * v.hi - 1.0};
    return outlineVerdict(1.0 - (x.maxSquare() + y.maxSquare()), 1.0 - (x.minSquare() + y.minSquare()));
}

/// Every texel a lookup in [u, v] can pick (texel() floors fl(u W), monotone in u), if few.
AlphaVerdict textureVerdict(const AlphaMap& m, const Span& u, const Span& v) {
    if (m.width == 0 || m.height == 0) return AlphaVerdict::Opaque;  // lookup(): opaque
    const double x0 = std::floor(u.lo * double(m.width)), x1 = std::floor(u.hi * double(m.width));
    const double y0 = std::floor(v.lo * double(m.height)), y1 = std::floor(v.hi * double(m.height));
    if (!(x1 - x0 < 16.0) || !(y1 - y0 < 16.0) || !((x1 - x0 + 1.0) * (y1 - y0 + 1.0) <= 256.0)) return AlphaVerdict::Mixed;
    if (!(std::abs(x0) < 0x1p52 && std::abs(y0) < 0x1p52)) return AlphaVerdict::Mixed;
    bool anyOpaque = false, anyClear = false;
    for (int64_t y = int64_t(y0); y <= int64_t(y1); ++y)
        for (int64_t x = int64_t(x0); x <= int64_t(x1); ++x) {
            const bool opaque = m.at(uint32_t(wrapIndex(x, m.width, m.wrapS)), uint32_t(wrapIndex(y, m.height, m.wrapT)));
            (opaque ? anyOpaque : anyClear) = true;
            if (anyOpaque && anyClear) return AlphaVerdict::Mixed;
        }
    return anyOpaque ? AlphaVerdict::Opaque : AlphaVerdict::Clear;
}

/// uv' = T (b0 uv0 + b1 uv1 + b2 uv2): the texture coordinates of barycentrics b on entry @p e,
/// in the one order lookup() and verdictOver() both round in.
glm::dvec2 mappedUv(const AlphaEntry& e, const AlphaMap& m, double b0, double b1, double b2) {
    const double u0 = (b0 * e.uv[0].x + b1 * e.uv[1].x) + b2 * e.uv[2].x;
    const double v0 = (b0 * e.uv[0].y + b1 * e.uv[1].y) + b2 * e.uv[2].y;
    return {(m.transform[0] * u0 + m.transform[1] * v0) + m.transform[2], (m.transform[3] * u0 + m.transform[4] * v0) + m.transform[5]};
}

AlphaEntry quadEntry(uint32_t map, bool upper) {
    AlphaEntry e;
    e.map = map;
    e.uv = upper ? std::array<glm::dvec2, 3>{glm::dvec2(0, 0), glm::dvec2(1, 1), glm::dvec2(0, 1)}
                 : std::array<glm::dvec2, 3>{glm::dvec2(0, 0), glm::dvec2(1, 0), glm::dvec2(1, 1)};
    return e;
}

}  // namespace

AlphaMap AlphaMap::texture(uint32_t width, uint32_t height, const std::vector<uint8_t>& opaque) {
    AlphaMap m;
    m.width = width, m.height = height;
    m.bits.assign((size_t(width) * height + 63) / 64, 0);
    for (uint32_t j = 0; j < height; ++j)
        for (uint32_t i = 0; i < width; ++i) m.set(i, j, opaque[size_t(j) * width + i] != 0);
    return m;
}

void AlphaMap::set(uint32_t i, uint32_t j, bool opaque) {
    const size_t k = size_t(j) * width + i;
    if (opaque) bits[k >> 6] |= 1ull << (k & 63);
    else bits[k >> 6] &= ~(1ull << (k & 63));
}

AlphaTable::AlphaTable() {
    AlphaMap leaf, petal;
    leaf.shape = AlphaShape::Leaf, leaf.name = "leaf outline";
    petal.shape = AlphaShape::Petal, petal.name = "petal outline";
    const uint32_t l = addMap(std::move(leaf)), p = addMap(std::move(petal));
    entries_.resize(1);  // id 0: no alpha
    entries_.push_back(quadEntry(l, false));
    entries_.push_back(quadEntry(l, true));
    entries_.push_back(quadEntry(p, false));
    entries_.push_back(quadEntry(p, true));
}

std::shared_ptr<const AlphaTable> AlphaTable::builtin() {
    static const auto table = std::make_shared<const AlphaTable>();
    return table;
}

uint32_t AlphaTable::addMap(AlphaMap map) {
    maps_.push_back(std::move(map));
    return uint32_t(maps_.size() - 1);
}

uint32_t AlphaTable::addEntry(const AlphaEntry& entry) {
    // Ids from kTranslucentIdBase up name translucent surfaces (Translucency.h).
    if (entries_.size() >= kTranslucentIdBase)
        fail("alpha", "more than {} alpha-tested triangles with distinct texture coordinates", kTranslucentIdBase - 1);
    if (std::isfinite(entry.maxDistance)) distances_ = true;
    entries_.push_back(entry);
    return uint32_t(entries_.size() - 1);
}

uint32_t AlphaTable::withDistance(uint32_t id, double maxDistance) {
    AlphaEntry entry;
    if (id != 0 && id < entries_.size()) entry = entries_[id];
    else {
        if (solid_ == ~0u) {
            AlphaMap solid;
            solid.shape = AlphaShape::Solid, solid.name = "opaque";
            solid_ = addMap(std::move(solid));
        }
        entry.map = solid_;
    }
    entry.maxDistance = maxDistance;
    distances_ = true;
    return addEntry(entry);
}

AlphaLookup AlphaTable::lookup(uint32_t id, double b0, double b1, double b2) const {
    if (id == 0 || id >= entries_.size()) return {};
    const AlphaEntry& e = entries_[id];
    const AlphaMap& m = maps_[e.map];
    const glm::dvec2 uv = mappedUv(e, m, b0, b1, b2);
    const double u = uv.x, v = uv.y;
    switch (m.shape) {
        case AlphaShape::Leaf: return outline(4.0 * u * (1.0 - u) - std::abs(2.0 * v - 1.0));
        case AlphaShape::Petal: {
            const double x = 2.0 * u - 1.0, y = 2.0 * v - 1.0;
            return outline(1.0 - (x * x + y * y));
        }
        case AlphaShape::Solid: return {};
        case AlphaShape::Texture: break;
    }
    if (m.width == 0 || m.height == 0 || !std::isfinite(u) || !std::isfinite(v)) return {};
    AlphaLookup out;
    const int64_t i = wrapIndex(texel(u * double(m.width), out.tie), m.width, m.wrapS);
    const int64_t j = wrapIndex(texel(v * double(m.height), out.tie), m.height, m.wrapT);
    out.opaque = m.at(uint32_t(i), uint32_t(j));
    return out;
}

AlphaVerdict AlphaTable::verdictOver(uint32_t id, std::span<const std::array<double, 3>> corners, double pad) const {
    if (id == 0 || id >= entries_.size()) return AlphaVerdict::Opaque;
    const AlphaEntry& e = entries_[id];
    const AlphaMap& m = maps_[e.map];
    if (m.shape == AlphaShape::Solid) return AlphaVerdict::Opaque;
    if (corners.empty() || !(pad >= 0.0) || !(pad < 1.0)) return AlphaVerdict::Mixed;
    // uv' is affine in b: uv'_c = sum_i b_i q_ic + t_c. Each corner's uv' in lookup()'s own order;
    // a b within pad moves uv'_c by at most pad sum_i |q_ic|, and the lookup's rounding (a few
    // ulps of the magnitudes involved) is covered by 1e-12 of them.
    const std::array<double, 6>& t = m.transform;
    double bMax = 0.0;
    Span u, v;
    for (const std::array<double, 3>& b : corners) {
        const glm::dvec2 uv = mappedUv(e, m, b[0], b[1], b[2]);
        u.add(uv.x), v.add(uv.y);
        bMax = std::max({bMax, std::abs(b[0]), std::abs(b[1]), std::abs(b[2])});
    }
    double qu = 0.0, qv = 0.0, mu = 0.0, mv = 0.0;  // sum_i |q_i| and the magnitude of the terms
    for (const glm::dvec2& c : e.uv) {
        qu += std::abs(t[0] * c.x + t[1] * c.y), qv += std::abs(t[3] * c.x + t[4] * c.y);
        mu += std::abs(t[0] * c.x) + std::abs(t[1] * c.y), mv += std::abs(t[3] * c.x) + std::abs(t[4] * c.y);
    }
    u.widen(pad * qu + 1e-12 * (1.0 + (bMax + pad) * mu + std::abs(t[2])));
    v.widen(pad * qv + 1e-12 * (1.0 + (bMax + pad) * mv + std::abs(t[5])));
    if (!std::isfinite(u.lo) || !std::isfinite(u.hi) || !std::isfinite(v.lo) || !std::isfinite(v.hi))
        return AlphaVerdict::Mixed;
    switch (m.shape) {
        case AlphaShape::Leaf:
        case AlphaShape::Petal: {
            // Outlines live in [0, 1]^2; beyond 16 their values' rounding could near kOutlineTie.
            const double far = std::max({std::abs(u.lo), std::abs(u.hi), std::abs(v.lo), std::abs(v.hi)});
            if (!(far <= 16.0)) return AlphaVerdict::Mixed;
            return m.shape == AlphaShape::Leaf ? leafVerdict(u, v) : petalVerdict(u, v);
        }
        case AlphaShape::Solid: return AlphaVerdict::Opaque;
        case AlphaShape::Texture: break;
    }
    return textureVerdict(m, u, v);
}

bool AlphaTable::outlineOf(uint32_t id, AlphaOutline& out) const {
    if (id == 0 || id >= entries_.size() || std::isfinite(entries_[id].maxDistance)) return false;
    const AlphaEntry& e = entries_[id];
    const AlphaMap& m = maps_[e.map];
    if (m.shape != AlphaShape::Leaf && m.shape != AlphaShape::Petal) return false;
    out.shape = m.shape, out.uv = e.uv, out.transform = m.transform;
    return true;
}

size_t AlphaTable::bytes() const {
    size_t total = sizeof(AlphaTable) + entries_.size() * sizeof(AlphaEntry);
    for (const AlphaMap& m : maps_) total += m.bytes();
    return total;
}

AlphaLookup AlphaTable::lookupAlong(uint32_t id, const glm::vec3& v0, const glm::vec3& v1, const glm::vec3& v2,
                                     const glm::dvec3& origin, const glm::dvec3& direction) const {
    const glm::dvec3 a[3] = {glm::dvec3(v0) - origin, glm::dvec3(v1) - origin, glm::dvec3(v2) - origin};
    double e[3];  // the line's signed volume with the edge opposite vertex i: its barycentric
    for (int i = 0; i < 3; ++i) e[i] = glm::dot(direction, glm::cross(a[(i + 1) % 3], a[(i + 2) % 3]));
    const double sum = (e[0] + e[1]) + e[2];
    if (!(sum != 0.0)) return lookup(id, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0);
    return lookup(id, e[0] / sum, e[1] / sum, e[2] / sum);
}

}  // namespace penumbra
