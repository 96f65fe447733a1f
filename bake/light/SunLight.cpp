#include "bake/light/SunLight.h"

#include <glm/gtc/constants.hpp>
#include <glm/trigonometric.hpp>

namespace penumbra {

glm::dvec3 sunIrradianceFromRadiance(const glm::dvec3& radiance, double diameterDeg) {
    // Projected solid angle of a cone of half-angle a seen head-on: pi sin^2(a).
    double s = std::sin(glm::radians(diameterDeg) * 0.5);
    return radiance * (glm::pi<double>() * s * s);
}

}  // namespace penumbra
