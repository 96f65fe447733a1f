#include "stream/AlphaTable.h"

#include "stream/util/Error.h"
#include "stream/Translucency.h"
#include "stream/Triangle.h"

#include <glm/geometric.hpp>

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
    const double u0 = (b0 * e.uv[0].x + b1 * e.uv[1].x) + b2 * e.uv[2].x;
    const double v0 = (b0 * e.uv[0].y + b1 * e.uv[1].y) + b2 * e.uv[2].y;
    const double u = (m.transform[0] * u0 + m.transform[1] * v0) + m.transform[2];
    const double v = (m.transform[3] * u0 + m.transform[4] * v0) + m.transform[5];
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
