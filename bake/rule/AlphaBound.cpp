#include "bake/rule/AlphaBound.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>

namespace penumbra {
namespace {

constexpr double kUnit = 0x1p-53;  // u, the unit roundoff of double
constexpr size_t kMaxVertices = 32;

double norm1(const glm::dvec3& x) { return (std::abs(x.x) + std::abs(x.y)) + std::abs(x.z); }

}  // namespace

AlphaVerdict alphaOverBound(const AlphaTable& table, const BlockerTriangle& t, const glm::dvec3& r, const ConvexBound& bound) {
    const size_t n = bound.vertices.size();
    if (!t.valid || n == 0 || n > kMaxVertices) return AlphaVerdict::Mixed;
    const double w = bound.w;
    glm::dvec3 normal[3];  // (b - a) x (r - a) per edge: E_e(l) = (l - w a) . normal
    double scale[3];       // |b - a|_1 |r - a|_1 per edge, for the rounding bound
    for (int e = 0; e < 3; ++e) {
        const glm::dvec3 edge = t.v[(e + 1) % 3] - t.v[e], rel = r - t.v[e];
        normal[e] = glm::cross(edge, rel);
        scale[e] = norm1(edge) * norm1(rel);
    }
    std::array<std::array<double, 3>, kMaxVertices> value;  // E_e at each vertex
    double farthest = 0.0;                                     // max |l|_1 over the hull
    for (size_t k = 0; k < n; ++k) {
        const glm::dvec3& l = bound.vertices[k];
        for (int e = 0; e < 3; ++e) value[k][e] = glm::dot(l - w * t.v[e], normal[e]);
        farthest = std::max(farthest, norm1(l));
    }
    // Delta: what rounding can move the sum of the three E_e by, in any evaluation, at most;
    // |l - w a|_1 <= |l|_1 + w |a|_1, and (1 + 4u) covers those norms' own rounding. The sums'
    // rounding is added below.
    double delta = 0.0, spread = 0.0;
    for (int e = 0; e < 3; ++e) delta += 16.0 * kUnit * ((farthest + w * norm1(t.v[e])) * (1.0 + 4.0 * kUnit)) * scale[e];
    for (size_t k = 0; k < n; ++k) spread = std::max(spread, norm1({value[k][0], value[k][1], value[k][2]}));
    delta += 4.0 * kUnit * spread;
    // The denominator's sign over the hull is its sign at the vertices (it is linear in l).
    std::array<double, kMaxVertices> sums;
    for (size_t k = 0; k < n; ++k) sums[k] = (value[k][0] + value[k][1]) + value[k][2];
    const double sign = sums[0] > 0.0 ? 1.0 : -1.0;
    double lowest = INFINITY;
    for (size_t k = 0; k < n; ++k) lowest = std::min(lowest, sign * sums[k] - delta);
    if (!(lowest > 8.0 * delta) || !std::isfinite(lowest)) return AlphaVerdict::Mixed;
    std::array<std::array<double, 3>, kMaxVertices> corners;
    double largest = 0.0;
    for (size_t k = 0; k < n; ++k) {
        // barycentricsAtEdges()'s order: b0 = E_1 / sum, b1 = E_2 / sum, b2 = E_0 / sum.
        corners[k] = {value[k][1] / sums[k], value[k][2] / sums[k], value[k][0] / sums[k]};
        largest = std::max({largest, std::abs(corners[k][0]), std::abs(corners[k][1]), std::abs(corners[k][2])});
    }
    // A computed barycentric is within 2 (1 + |b|) Delta / S + 4u |b| of its exact value (S >= the
    // lowest denominator); the vertices' and the hits' errors add up, hence twice that, rounded up.
    const double pad = 2.0 * 8.0 * (1.0 + largest) * (delta / lowest + 4.0 * kUnit);
    const AlphaVerdict map = table.verdictOver(t.alpha, std::span(corners.data(), n), pad);
    if (map == AlphaVerdict::Opaque && std::isfinite(table.maxDistance(t.alpha))) return AlphaVerdict::Mixed;
    return map;
}

}  // namespace penumbra
