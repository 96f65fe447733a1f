#pragma once
/// @file AlphaTable.h
/// @brief Cut-out (alpha-tested) blockers: what is opaque where on an alpha triangle.
///
/// An alpha triangle carries an *alpha id* in the high bits of Triangle::flags (Triangle.h,
/// alphaIdOf()). The id names an AlphaEntry of the bake's AlphaTable: an AlphaMap (an analytic
/// outline or a thresholded texture) and the UV of the triangle's three corners. The record stays
/// 40 bytes and flows unchanged through buckets and .ptri files.
///
/// The test, identical in every method (bake/rule/AlphaRule.h computes the barycentrics):
///  - uv = b0 uv0 + b1 uv1 + b2 uv2 in double, then the map's affine transform
///    (KHR_texture_transform: uv' = T uv);
///  - analytic maps: opaque iff the outline's function f(uv') > 0;
///  - textures: nearest texel, x = u' W, y = v' H, i = floor(x), j = floor(y) wrapped per axis
///    (repeat, clamp to edge, mirrored repeat); opaque iff the texel's bit is set. Bits are the
///    alpha threshold applied once when the texture is decoded (alpha x factor >= cutoff), so no
///    method ever compares against the cutoff itself.
/// A hit within roundoff of a texel edge or of an outline (f within 1e-9) is a *tie*
/// (AlphaLookup::tie); every method computes the same double values, so methods only differ
/// there when their edge values differ, which the rule's own edge ties already cover.
///
/// Built-in ids 1..kBuiltinAlphaCount-1 are the procedural outlines on the canonical quad layout
/// (corners (0,0), (1,0), (1,1), (0,1); the quad split as (0,1,2) "lower" and (0,2,3) "upper"),
/// so generators need no table of their own.

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

/// Built-in alpha ids: analytic outlines on the canonical quad layout.
enum BuiltinAlpha : uint32_t {
    kAlphaLeafLower = 1,   ///< leaf outline |2v - 1| < 4u(1 - u), triangle (0,0) (1,0) (1,1)
    kAlphaLeafUpper = 2,   ///< the same leaf, triangle (0,0) (1,1) (0,1)
    kAlphaPetalLower = 3,  ///< petal outline (2u - 1)^2 + (2v - 1)^2 < 1 (a disc), lower triangle
    kAlphaPetalUpper = 4,  ///< the same petal, upper triangle
    kBuiltinAlphaCount = 5,
};

/// Texture coordinate wrap per axis (glTF sampler wrapS/wrapT).
enum class AlphaWrap : uint8_t { Repeat, Clamp, Mirror };

/// What decides opacity on a map.
enum class AlphaShape : uint8_t { Texture, Leaf, Petal, Solid /* opaque everywhere: a max_distance id of an opaque triangle */ };

/// @brief One alpha map: an analytic outline or a 1-bit texture.
struct AlphaMap {
    AlphaShape shape = AlphaShape::Texture;
    uint32_t width = 0, height = 0;          ///< texels (textures only)
    AlphaWrap wrapS = AlphaWrap::Repeat, wrapT = AlphaWrap::Repeat;
    std::vector<uint64_t> bits;              ///< row-major, row 0 at v = 0; bit set: opaque
    /// Affine uv' = (t[0] u + t[1] v + t[2], t[3] u + t[4] v + t[5]) (KHR_texture_transform).
    std::array<double, 6> transform{1, 0, 0, 0, 1, 0};
    std::string name;                        ///< for messages: the material or outline

    /// @brief A @p width x @p height texture whose texel (i, j) is opaque when @p opaque[j W + i].
    static AlphaMap texture(uint32_t width, uint32_t height, const std::vector<uint8_t>& opaque);
    /// @brief Sets texel (@p i, @p j)'s bit.
    void set(uint32_t i, uint32_t j, bool opaque);
    /// @brief Texel (@p i, @p j)'s bit.
    bool at(uint32_t i, uint32_t j) const {
        const size_t k = size_t(j) * width + i;
        return (bits[k >> 6] >> (k & 63)) & 1u;
    }
    size_t bytes() const { return sizeof(AlphaMap) + bits.size() * sizeof(uint64_t) + name.size(); }
};

/// @brief One alpha id: a map and the UV of the triangle's corners.
struct AlphaEntry {
    uint32_t map = 0;
    std::array<glm::dvec2, 3> uv{};
    /// A scene entry's "max_distance": the hit blocks only within this distance of the receiver
    /// (bake/rule/AlphaRule.h, alphaAtHit). Infinity: no limit.
    double maxDistance = INFINITY;
};

/// @brief An id whose test depends on the barycentrics alone through an analytic outline: what
/// lookup() reads for it, so that a SIMD form can repeat its operations (bake/cast/OutlineTest.h).
struct AlphaOutline {
    AlphaShape shape = AlphaShape::Leaf;  ///< Leaf or Petal
    std::array<glm::dvec2, 3> uv{};
    std::array<double, 6> transform{1, 0, 0, 0, 1, 0};
};

/// @brief The result of one alpha test.
struct AlphaLookup {
    bool opaque = true;
    bool tie = false;  ///< within roundoff of a texel edge or of an outline
};

/// @brief What every alpha test over a region of a triangle agrees on (AlphaTable::verdictOver()).
enum class AlphaVerdict : uint8_t {
    Mixed,   ///< the region may hold both results, or the map cannot tell cheaply: test each hit
    Opaque,  ///< every test in the region passes
    Clear,   ///< every test in the region fails
};

/// @brief Every alpha map and alpha id of a bake. Read-only once the bake starts, so methods
/// share one table across threads.
class AlphaTable {
public:
    /// A table holding the built-in outlines (ids 1..kBuiltinAlphaCount-1).
    AlphaTable();

    /// @brief The shared table of built-in outlines, used when a bake sets none.
    static std::shared_ptr<const AlphaTable> builtin();

    /// @brief Adds a map; @return its index.
    uint32_t addMap(AlphaMap map);
    /// @brief Adds an alpha id; @return it (>= kBuiltinAlphaCount).
    /// @throw InputError when the 24-bit id space of Triangle::flags is exhausted.
    uint32_t addEntry(const AlphaEntry& entry);

    /// @brief An id that tests like @p id (0: an opaque triangle) and also limits the blocking
    /// hit to @p maxDistance from the receiver (a scene entry's "max_distance"); @return it.
    uint32_t withDistance(uint32_t id, double maxDistance);
    /// @brief The hit distance limit of @p id (infinity: none).
    double maxDistance(uint32_t id) const { return id < entries_.size() ? entries_[id].maxDistance : INFINITY; }
    /// @brief True when some id limits the hit distance.
    bool hasDistances() const { return distances_; }

    /// @brief The test at barycentrics (@p b0, @p b1, @p b2) of alpha id @p id. An id the table
    /// does not hold is opaque (never less blocking than the triangle without alpha).
    AlphaLookup lookup(uint32_t id, double b0, double b1, double b2) const;
    /// @brief The test where the line through @p origin along @p direction meets triangle
    /// (@p v0, @p v1, @p v2) of alpha id @p id: its barycentrics are the line's signed volumes
    /// with the three edges, normalized (a line in the triangle's plane takes its centroid).
    /// Rasterizers (camera, light views, lightmap projections) call it for a fragment they keep.
    AlphaLookup lookupAlong(uint32_t id, const glm::vec3& v0, const glm::vec3& v1, const glm::vec3& v2, const glm::dvec3& origin,
                            const glm::dvec3& direction) const;

    /// @brief The result every lookup(@p id, b) shares for the b within @p pad (per coordinate)
    /// of the convex hull of @p corners (barycentrics), the lookup's own rounding included:
    /// Opaque or Clear only when each of those lookups certainly gives it (exact by construction,
    /// so a caster may skip them), otherwise Mixed. Textures are judged over at most 256 texels.
    /// The map only: a caller of an id with a max_distance tests the distance itself.
    AlphaVerdict verdictOver(uint32_t id, std::span<const std::array<double, 3>> corners, double pad) const;
    /// @brief Whether @p id's whole test is an analytic outline (Leaf or Petal, no max_distance);
    /// if so, @p out gets what lookup() reads for it.
    bool outlineOf(uint32_t id, AlphaOutline& out) const;

    size_t entries() const { return entries_.size(); }
    const AlphaMap& map(uint32_t index) const { return maps_[index]; }
    /// @brief Bytes held, for the memory plan.
    size_t bytes() const;

private:
    std::vector<AlphaMap> maps_;
    std::vector<AlphaEntry> entries_;  ///< index = alpha id (entry 0 unused)
    uint32_t solid_ = ~0u;             ///< the Solid map, once a distance id of an opaque triangle needs it
    bool distances_ = false;
};

}  // namespace penumbra
