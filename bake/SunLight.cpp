#include "bake/SunLight.h"

#include "stream/Error.h"

#include <glm/geometric.hpp>
#include <glm/gtc/constants.hpp>
#include <glm/trigonometric.hpp>

#include <cmath>

namespace penumbra {

glm::dvec3 sunIrradianceFromRadiance(const glm::dvec3& radiance, double diameterDeg) {
    // Projected solid angle of a cone of half-angle a seen head-on: pi sin^2(a).
    double s = std::sin(glm::radians(diameterDeg) * 0.5);
    return radiance * (glm::pi<double>() * s * s);
}

std::vector<LightDesc> placeSuns(const std::vector<LightDesc>& lights, const glm::dvec3& lo, const glm::dvec3& hi) {
    const bool empty = !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z);
    const glm::dvec3 center = empty ? glm::dvec3(0.0) : 0.5 * (lo + hi);
    // A scene of one point (or none) still needs a finite distance; 1e-3 keeps floats sane.
    const double extent = empty ? 1.0 : std::max(glm::length(hi - lo), 1e-3);
    std::vector<LightDesc> out = lights;
    for (LightDesc& l : out) {
        if (l.type != LightType::Sun) continue;
        validateLight(l);
        const glm::dvec3 dir = glm::normalize(l.direction);
        const double distance = kSunDistanceFactor * extent;
        l.center = center - distance * dir;
        l.normal = dir;  // the disk emits toward the scene
        l.radius = distance * std::tan(glm::radians(l.angularDiameterDeg) * 0.5);
        l.placed = true;
        validateLight(l);
    }
    return out;
}

}  // namespace penumbra
