#pragma once
/// @file Light.h
/// @brief Area lights, their stratified jittered samples, sample sets and light-sample groups.

#include "bake/rule/ConvexBound.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace penumbra {

/// Sun: a directional light; its samples are directions (w = 0), see LightSamples.
enum class LightType { Rect, Disk, Sphere, Polygon, Sun };

/// @brief A light as described in the scene file.
struct LightDesc {
    LightType type = LightType::Rect;
    glm::dvec3 center{0.0};
    glm::dvec3 u{1, 0, 0}, v{0, 0, 1};  ///< rect: full edge vectors; it emits on the side of u x v
    glm::dvec3 normal{0, -1, 0};        ///< disk: emitting side
    double radius = 0.5;                ///< disk and sphere
    std::vector<glm::dvec3> polygon;    ///< polygon: convex, planar, in order
    glm::dvec3 radiance{1.0};           ///< RGB radiance (W / (m^2 sr)), used by shading
    glm::dvec3 direction{0, -1, 0};     ///< sun: direction the light travels (sun -> scene)
    double angularDiameterDeg = 0.53;   ///< sun: apparent diameter of its disk
    glm::dvec3 irradiance{1.0};         ///< sun: RGB irradiance (W/m^2) on a surface facing it
    int samples = 256;
    int sampleSets = 8;
    std::string where = "light";  ///< "scene.json: lights[0]", for messages

    /// Emitting area (planar lights) or volume-equivalent surface area (sphere).
    double area() const;
    /// Unit normal of the emitting side of a planar light; zero for spheres and suns, which have
    /// no emitter cosine.
    glm::dvec3 emitterNormal() const;
    /// The corners of a rect (counter-clockwise from center - u/2 - v/2) or a polygon's vertices;
    /// empty for other lights, whose outline is not a polygon.
    std::vector<glm::dvec3> outline() const;
};

/// @brief Up to 64 spatially close samples of one light; one 64-bit mask word.
struct LightSampleGroup {
    uint32_t light = 0;
    uint32_t first = 0;  ///< index of its first sample in LightSamples (global sample index)
    uint32_t count = 0;  ///< 1..64
    ConvexBound bound;   ///< contains the group's samples in every set

    uint64_t fullMask() const { return count == 64 ? ~0ull : (1ull << count) - 1ull; }
};

/// @brief Every light's samples in every set. Sample k of set s is positions[s * sampleCount + k];
/// the samples of all lights are concatenated in light order, and each group's samples are
/// contiguous. Positions are float32 (as dumped) so every method casts from identical samples.
///
/// A sample is homogeneous (BlockingRule.h): a point (w = 1) for area lights, a direction towards
/// the light (w = 0) for suns. A sun's directions lie on the plane at unit distance along its axis
/// (axis + tan(radius) * disk offset, not normalised), so its groups have planar bounds like any
/// disk light's and the sample mask table applies unchanged.
struct LightSamples {
    int sets = 1;
    int sampleCount = 0;  ///< K: samples per set, all lights together
    std::vector<glm::vec3> positions;
    std::vector<LightSampleGroup> groups;
    std::vector<ConvexBound> lightBounds;      ///< Delta_L per light (all sets)
    std::vector<uint32_t> lightFirstGroup;     ///< groups of light i: [first[i], first[i+1])
    std::vector<uint32_t> sampleLight;         ///< light of each sample

    const glm::vec3& position(int set, int k) const { return positions[size_t(set) * sampleCount + k]; }
    int lightCount() const { return int(lightBounds.size()); }
    int groupCount() const { return int(groups.size()); }
    /// The homogeneous weight of light @p light's samples: 1 (points) or 0 (directions).
    double w(uint32_t light) const { return lightBounds[light].w; }
    /// The homogeneous weight of global sample @p k.
    double sampleW(uint32_t k) const { return w(sampleLight[k]); }
};

/// @brief Checks a light description; throws InputError naming light.where and the bad value
/// (zero area, non-unit-count samples, non-planar or non-convex polygon...).
void validateLight(const LightDesc& light);

/// @brief Projects a polygon light's vertices onto their mean plane when they are off it by more
/// than 1e-6 of its size (validateLight() allows 1e-4: coordinates typed to four decimals), so
/// that its samples, bounds and tables all see one plane. Other lights are left as they are.
void flattenPolygon(LightDesc& light);

/// @brief A sun as the disk of directions it is sampled as: centre at the unit vector towards the
/// sun, normal along the direction of travel, radius tan(angular diameter / 2).
LightDesc sunDirectionDisk(const LightDesc& sun);

/// @brief Stratified, jittered samples for every light, @p groupSize (<= 64) per group.
/// Deterministic in @p seed. Sets beyond a light's own sampleSets repeat its sets cyclically.
/// A sun is sampled as a disk of directions (stratified like a disk light).
/// @throw InputError for an invalid light.
LightSamples generateLightSamples(const std::vector<LightDesc>& lights, int groupSize, uint64_t seed);

/// @brief The layout generateLightSamples() gives (sets, sample count, groups with their first
/// sample and count, one default bound per light), without positions or bounds: what a memory
/// plan reads, before any of the samples' bytes are spent (65,536 samples x 64 sets took
/// 424 MB to generate before a budget of 200M was refused).
/// @throw InputError for an invalid light.
LightSamples lightSampleLayout(const std::vector<LightDesc>& lights, int groupSize);

/// @brief The sample set a receiver uses: a hash of its index, so it is independent of tiling.
inline int sampleSetOf(uint64_t receiverIndex, int sets, uint64_t seed);

}  // namespace penumbra

#include "stream/util/Random.h"

namespace penumbra {
inline int sampleSetOf(uint64_t receiverIndex, int sets, uint64_t seed) {
    return int(hashIndex(seed ^ 0x5e75u, receiverIndex) % uint64_t(sets));
}
}  // namespace penumbra
