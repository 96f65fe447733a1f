#include "bake/light/SunLight.h"

#include <glm/gtc/constants.hpp>
#include <glm/trigonometric.hpp>

namespace penumbra {

glm::dvec3 sunIrradianceFromRadiance(const glm::dvec3& radiance, double diameterDeg) {
    // Projected solid angle of a cone of half-angle a seen head-on: pi sin^2(a).
    double s = std::sin(glm::radians(diameterDeg) * 0.5);
    return radiance * (glm::pi<double>() * s * s);
}

double sunMeanCosine(double diameterDeg) {
    const double t = std::tan(glm::radians(diameterDeg) * 0.5), t2 = t * t;
    // 2 (sqrt(1 + t^2) - 1) / t^2, written without the cancellation for small t.
    return 2.0 / (std::sqrt(1.0 + t2) + 1.0);
}

}  // namespace penumbra
