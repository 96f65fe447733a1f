#pragma once
/// @file SunLight.h
/// @brief Directional sun lights, realized as a far disk so every caster sees ordinary samples.
///
/// A sun is a cone of directions (its angular diameter). Rather than teach the casters and the
/// penumbra volumes about directions, the sun becomes a disk light at distance D = 1e5 x the
/// extent of the scene, of radius D tan(diameter / 2), facing the scene. Its samples are then
/// points like any other light's, so hpc, reference and embree cast from identical points and
/// the blocking rule and the penumbra volumes (built from the cone spanned by the far disk)
/// apply unchanged. Rays from one sample to different receivers diverge by at most
/// extent / D = 1e-5 rad, far below the sun's own 4.6e-3 rad radius.

#include "bake/Light.h"

#include <glm/common.hpp>
#include <glm/vec3.hpp>

#include <cmath>

#include <vector>

namespace penumbra {

/// @brief Distance of a placed sun's disk in units of the scene's extent.
inline constexpr double kSunDistanceFactor = 1e5;

/// @brief Returns @p lights with every sun placed as a far disk beyond the box [@p lo, @p hi]
/// (everything that casts or receives). Other lights are returned unchanged.
/// @throw InputError for an invalid sun (zero direction, bad angular diameter).
std::vector<LightDesc> placeSuns(const std::vector<LightDesc>& lights, const glm::dvec3& lo, const glm::dvec3& hi);

/// @brief Irradiance (W/m^2, normal to the sun's direction) of a sun of uniform radiance @p radiance
/// and angular diameter @p diameterDeg: L times the solid angle of the disk of directions.
glm::dvec3 sunIrradianceFromRadiance(const glm::dvec3& radiance, double diameterDeg);

/// @brief Incrementally grown axis-aligned box; starts empty.
struct SceneBox {
    glm::dvec3 lo{INFINITY}, hi{-INFINITY};
    void add(const glm::dvec3& p) { lo = glm::min(lo, p), hi = glm::max(hi, p); }
    bool empty() const { return !(lo.x <= hi.x); }
};

}  // namespace penumbra
