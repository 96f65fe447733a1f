#include "bake/shading/ReceiverShading.h"

#include "stream/Error.h"

#include <glm/geometric.hpp>
#include <glm/gtc/constants.hpp>

#include <bit>
#include <cmath>

namespace penumbra {
glm::dvec3 radianceFromPower(const LightDesc& l, const glm::dvec3& power) {
    const double pi = glm::pi<double>();
    switch (l.type) {
        case LightType::Sun: fail(l.where, "a sun takes \"irradiance\" or \"radiance\", not \"power\"");
        // A Lambertian sphere of radiance L emits L * pi per unit area over 4 pi r^2.
        case LightType::Sphere: return power / (4.0 * pi * pi * l.radius * l.radius);
        default: return power / (pi * l.area());  // one-sided Lambertian emitter
    }
}

ReceiverShader::ReceiverShader(const std::vector<LightDesc>& lights, const LightSamples& samples,
                               const ReceiverSet& receivers, std::span<const uint32_t> sampleSets)
    : samples_(samples), receivers_(receivers), sets_(sampleSets) {
    for (const LightDesc& l : lights) {
        PerLight p;
        p.samples = l.samples;
        if (l.type == LightType::Sun) {
            // Every sample is a direction carrying an equal share of the sun's irradiance.
            p.sun = true, p.normal = glm::dvec3(0.0), p.weight = l.irradiance / double(l.samples);
        } else {
            // A sphere is seen as a disk of its radius from every direction.
            double area = l.type == LightType::Sphere ? M_PI * l.radius * l.radius : l.area();
            p.normal = l.emitterNormal(), p.weight = l.radiance * (area / l.samples);
        }
        lights_.push_back(p);
    }
}

void ReceiverShader::shade(uint32_t r, const uint64_t* groupWords, bool fullUmbra, ReceiverResults& out) const {
    const glm::dvec3 p(receivers_.position[r]), n(receivers_.normal[r]);
    const int set = int(sets_[r]);
    const bool perLight = out.lights > 1;
    uint64_t blocked = 0;
    glm::dvec3 total(0.0);
    for (int li = 0; li < samples_.lightCount(); ++li) {
        const PerLight& light = lights_[li];
        const bool planar = glm::dot(light.normal, light.normal) > 0;
        uint64_t lightBlocked = 0;
        glm::dvec3 e(0.0);
        for (uint32_t k = samples_.lightFirstGroup[li]; k < samples_.lightFirstGroup[li + 1]; ++k) {
            const LightSampleGroup& g = samples_.groups[k];
            const uint64_t word = fullUmbra ? g.fullMask() : (groupWords ? groupWords[k] : 0);
            lightBlocked += uint64_t(std::popcount(word));
            for (uint64_t visible = ~word & g.fullMask(); visible; visible &= visible - 1) {
                // A sun's sample is a direction (w = 0): the receiver's position does not matter.
                const glm::dvec3 l(samples_.position(set, int(g.first) + std::countr_zero(visible)));
                glm::dvec3 d = light.sun ? l : l - p;
                double dist2 = glm::dot(d, d);
                if (!(dist2 > 0)) continue;
                glm::dvec3 w = d / std::sqrt(dist2);
                // A zero normal (volume receivers) means no receiver cosine: fluence-like irradiance.
                double cosReceiver = n == glm::dvec3(0.0) ? 1.0 : std::max(0.0, glm::dot(n, w));
                if (light.sun) {
                    e += light.weight * cosReceiver;
                    continue;
                }
                double cosEmitter = planar ? std::max(0.0, -glm::dot(light.normal, w)) : 1.0;
                e += light.weight * (cosReceiver * cosEmitter / dist2);
            }
        }
        blocked += lightBlocked;
        total += e;
        if (perLight) {
            out.lightVisibility[size_t(r) * out.lights + li] = float(1.0 - double(lightBlocked) / light.samples);
            out.lightIrradiance[size_t(r) * out.lights + li] = glm::vec3(e);
        }
    }
    out.visibility[r] = samples_.sampleCount ? float(1.0 - double(blocked) / samples_.sampleCount) : 1.f;
    out.irradiance[r] = glm::vec3(total);
}

}  // namespace penumbra
