#pragma once
/// @file SunLight.h
/// @brief Directional sun lights: radiometry helpers and the scene box the pipeline grows.
///
/// A sun is a cone of directions (its angular diameter). Its samples are directions (w = 0 in
/// BlockingRule.h), not far points: every method casts a ray to infinity along each, and every
/// plane the caster builds takes them as points at infinity (sunDirectionDisk() in Light.h).

#include <glm/common.hpp>
#include <glm/vec3.hpp>

#include <cmath>

namespace penumbra {

/// @brief Irradiance (W/m^2, normal to the sun's direction) of a sun of uniform radiance @p radiance
/// and angular diameter @p diameterDeg: L times the solid angle of the disk of directions.
glm::dvec3 sunIrradianceFromRadiance(const glm::dvec3& radiance, double diameterDeg);

/// @brief The mean cosine, to the sun's axis, of its sample directions: they are spread uniformly
/// over the disk of radius t = tan(half the diameter) at unit distance (sunDirectionDisk()), so
/// the mean of 1 / sqrt(1 + rho^2) over that disk, 2 (sqrt(1 + t^2) - 1) / t^2. Dividing each
/// sample's share of the irradiance by it makes a surface facing the sun receive the irradiance
/// given (0.8 % short at 20 degrees without it).
double sunMeanCosine(double diameterDeg);

/// @brief Incrementally grown axis-aligned box; starts empty.
struct SceneBox {
    glm::dvec3 lo{INFINITY}, hi{-INFINITY};
    void add(const glm::dvec3& p) { lo = glm::min(lo, p), hi = glm::max(hi, p); }
    bool empty() const { return !(lo.x <= hi.x); }
};

}  // namespace penumbra
