#pragma once
/// @file EdgeBalance.h
/// @brief Checks in constant memory that a stream of triangles is a closed, consistently wound
/// surface: every directed edge a -> b appears as often as its reverse b -> a.
///
/// Closed casters (Sintorn et al. 2008) skip the faces of a closed solid that turn away from the
/// light, which is exact only when every segment that leaves the solid through such a face entered
/// it through another. That holds when the triangles' boundary cancels: each edge shared by faces
/// on both sides, wound oppositely. A `"closed": true` mark on a mesh with a hole, a crack, a
/// T-junction or a flipped face breaks it, and the shadows that the skipped faces cast are lost.
/// The scan pass cannot keep a solid's edges (a closed entry may have millions of triangles), so
/// it sums, over every directed edge, an antisymmetric hash of the edge's two vertices
///     E(a, b) = p(a) q(b) - p(b) q(a)   (mod 2^64),   E(b, a) = -E(a, b),
/// where p and q are independent 64-bit hashes of the vertex's float bits. A balanced set of
/// edges sums to exactly 0; an unbalanced one sums to 0 only by a coincidence of two 64-bit
/// sums (two independent pairs of hashes). Vertices are matched by their exact float values, as
/// the blocking rule sees them: corners that differ by rounding are not shared.
/// Degenerate triangles cancel themselves and change nothing.
///
/// OutwardVolume checks the winding: a closed surface wound inward would skip, for a receiver
/// inside it (a volume's voxel, a point), the very face through which its segments leave.

#include "stream/Triangle.h"

#include <glm/geometric.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>

namespace penumbra {

class EdgeBalance {
public:
    /// @brief Adds the three directed edges of @p t (v0 -> v1 -> v2 -> v0).
    void add(const Triangle& t) {
        const Key k[3] = {key(t.v[0]), key(t.v[1]), key(t.v[2])};
        for (int e = 0; e < 3; ++e) {
            const Key& a = k[e];
            const Key& b = k[(e + 1) % 3];
            first_ += a.p * b.q - b.p * a.q;
            second_ += a.r * b.s - b.r * a.s;
        }
    }
    /// @brief True when every directed edge added so far has its reverse (up to a 2^-128 chance).
    bool balanced() const { return first_ == 0 && second_ == 0; }
    void reset() { first_ = second_ = 0; }

private:
    struct Key {
        uint64_t p, q, r, s;
    };
    static uint64_t mix(uint64_t x) {  // splitmix64's finalizer
        x ^= x >> 30, x *= 0xbf58476d1ce4e5b9ull;
        x ^= x >> 27, x *= 0x94d049bb133111ebull;
        return x ^ (x >> 31);
    }
    static Key key(const glm::vec3& v) {
        uint32_t bits[3];
        for (int i = 0; i < 3; ++i) {
            const float c = v[i] + 0.0f;  // -0 and +0 are one point
            std::memcpy(&bits[i], &c, sizeof c);
        }
        const uint64_t xy = (uint64_t(bits[0]) << 32) | bits[1], z = bits[2];
        const uint64_t h = mix(xy ^ mix(z + 0x9e3779b97f4a7c15ull));
        return {mix(h + 1), mix(h + 2), mix(h + 3), mix(h + 4)};
    }

    uint64_t first_ = 0, second_ = 0;
};

/// @brief The signed volume of a closed surface (divergence theorem): positive when its triangles
/// are wound counter-clockwise seen from outside. Summed in double relative to the first vertex,
/// so a solid far from the origin keeps its precision.
class OutwardVolume {
public:
    void add(const Triangle& t) {
        if (!started_) origin_ = glm::dvec3(t.v[0]), started_ = true;
        const glm::dvec3 a = glm::dvec3(t.v[0]) - origin_, b = glm::dvec3(t.v[1]) - origin_, c = glm::dvec3(t.v[2]) - origin_;
        const double term = glm::dot(a, glm::cross(b, c));
        sum_ += term, magnitude_ += std::abs(term);
    }
    /// @brief True when the volume is positive beyond the sum's rounding (1e-9 of the terms'
    /// magnitudes): a flat or inward-wound surface is not.
    bool outward() const { return sum_ > 1e-9 * magnitude_; }
    void reset() { *this = {}; }

private:
    glm::dvec3 origin_{0.0};
    double sum_ = 0, magnitude_ = 0;
    bool started_ = false;
};

}  // namespace penumbra
