#pragma once
/// @file Triangle.h
/// @brief The record that flows through every stage: one world-space blocker triangle.

#include <glm/vec3.hpp>
#include <glm/geometric.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <span>

namespace penumbra {

/// Bits of Triangle::flags.
enum TriangleFlag : uint32_t {
    kTriangleAlphaMatte = 1u << 0,  ///< cut-out foliage; bucketed and replayed after opaque blockers
    /// Part of a closed (watertight) surface wound counter-clockwise seen from outside. A segment
    /// that enters the solid through such a triangle leaves it through another one that faces
    /// the segment's far end, so a triangle that faces away from the whole light can be skipped
    /// (Sintorn et al. 2008, "closed casters"; bake.closed_casters).
    kTriangleClosed = 1u << 1,
    /// The first triangle of one closed solid: the solid is this triangle and the closed ones that
    /// follow it in the stream up to the next solid start or open triangle. Lets the bake find the
    /// solids a light reaches inside (bake/ClosedSolids.h) without storing anything per solid.
    /// A run of closed triangles without it is taken as one solid, which is conservative.
    kTriangleSolidStart = 1u << 2,
    /// The scene entry says "cast_shadows": false: receiver scans and smooth shading see the
    /// triangle, every method skips it as a blocker (dropNonCasting(), BlockerBatch).
    kTriangleNoCast = 1u << 3,
};

/// Layout of Triangle::flags: bits 0..3 are the TriangleFlag bits, bits 4..7 the triangle's
/// receiver class (its entry's "receive_shadows" and "receiver_offset", SceneDesc::receiverClasses;
/// 0: the defaults), and bits 8..31 hold the triangle's alpha id (stream/AlphaTable.h), 0 for an
/// opaque triangle. A triangle with an alpha id also has kTriangleAlphaMatte, so that it is
/// bucketed last.
constexpr uint32_t kTriangleClassShift = 4;
constexpr uint32_t kTriangleClassMax = 15;
constexpr uint32_t kTriangleAlphaIdShift = 8;

/// The receiver class in @p flags (0: receives shadows, no offset).
constexpr uint32_t receiverClassOf(uint32_t flags) { return (flags >> kTriangleClassShift) & kTriangleClassMax; }
constexpr uint32_t kTriangleAlphaIdMax = (1u << 24) - 1;

/// The alpha id in @p flags (0: no alpha test).
constexpr uint32_t alphaIdOf(uint32_t flags) { return flags >> kTriangleAlphaIdShift; }
/// @p flags with alpha id @p id (kTriangleAlphaMatte set when @p id is not 0).
constexpr uint32_t withAlphaId(uint32_t flags, uint32_t id) {
    return (flags & ((1u << kTriangleAlphaIdShift) - 1)) | (id << kTriangleAlphaIdShift) |
           (id ? uint32_t(kTriangleAlphaMatte) : 0u);
}

/// @brief One triangle in world space. 40 bytes, trivially copyable, so chunks of them can be
/// written to and read from bucket files as raw bytes.
struct Triangle {
    std::array<glm::vec3, 3> v;
    uint32_t flags = 0;

    /// Twice the area is what the cross product gives; the area itself is what the buckets sort on.
    float area() const { return 0.5f * glm::length(glm::cross(v[1] - v[0], v[2] - v[0])); }
};
static_assert(sizeof(Triangle) == 40, "Triangle is a raw on-disk record");

/// @brief The largest float point not above @p p in any coordinate (@p below) or the smallest not
/// below it: float boxes built from double points still contain them.
inline glm::vec3 roundToFloat(const glm::dvec3& p, bool below) {
    glm::vec3 f(p);
    for (int a = 0; a < 3; ++a) {
        if (below && double(f[a]) > p[a]) f[a] = std::nextafter(f[a], -INFINITY);
        if (!below && double(f[a]) < p[a]) f[a] = std::nextafter(f[a], INFINITY);
    }
    return f;
}

/// @brief Moves the triangles of @p chunk that cast shadows to its front, in order, and
/// @return how many there are: what a method casts of a chunk ("cast_shadows": false entries
/// are read for the receivers' sake only).
inline size_t dropNonCasting(std::span<Triangle> chunk) {
    size_t kept = 0;
    for (const Triangle& t : chunk)
        if (!(t.flags & kTriangleNoCast)) chunk[kept++] = t;
    return kept;
}

/// True when all nine coordinates are finite.
inline bool isFinite(const Triangle& t) {
    for (const auto& p : t.v)
        for (int i = 0; i < 3; ++i)
            if (!(p[i] - p[i] == 0.0f)) return false;  // NaN and inf both fail
    return true;
}

}  // namespace penumbra
