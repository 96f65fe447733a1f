#include "bake/ReceiverShading.h"

#include <glm/geometric.hpp>

#include <bit>
#include <cmath>

namespace penumbra {
namespace {

glm::dvec3 emitterNormal(const LightDesc& l) {
    switch (l.type) {
        case LightType::Rect: return glm::normalize(glm::cross(l.u, l.v));
        case LightType::Disk: return glm::normalize(l.normal);
        case LightType::Polygon: {
            glm::dvec3 n(0.0);
            for (size_t i = 1; i + 1 < l.polygon.size(); ++i)
                n += glm::cross(l.polygon[i] - l.polygon[0], l.polygon[i + 1] - l.polygon[0]);
            return glm::normalize(n);
        }
        case LightType::Sphere: return glm::dvec3(0.0);
    }
    return glm::dvec3(0.0);
}

}  // namespace

ReceiverShader::ReceiverShader(const std::vector<LightDesc>& lights, const LightSamples& samples,
                               const ReceiverSet& receivers, std::span<const uint32_t> sampleSets)
    : samples_(samples), receivers_(receivers), sets_(sampleSets) {
    for (const LightDesc& l : lights) {
        // A sphere is seen as a disk of its radius from every direction.
        double area = l.type == LightType::Sphere ? M_PI * l.radius * l.radius : l.area();
        lights_.push_back({emitterNormal(l), l.radiance * (area / l.samples)});
    }
}

void ReceiverShader::shade(uint32_t r, const uint64_t* groupWords, bool fullUmbra, ReceiverResults& out) const {
    const glm::dvec3 p(receivers_.position[r]), n(receivers_.normal[r]);
    const int set = int(sets_[r]);
    uint64_t blocked = 0;
    glm::dvec3 e(0.0);
    for (int k = 0; k < samples_.groupCount(); ++k) {
        const LightSampleGroup& g = samples_.groups[k];
        const uint64_t word = fullUmbra ? g.fullMask() : (groupWords ? groupWords[k] : 0);
        blocked += uint64_t(std::popcount(word));
        const PerLight& light = lights_[g.light];
        const bool planar = glm::dot(light.normal, light.normal) > 0;
        for (uint64_t visible = ~word & g.fullMask(); visible; visible &= visible - 1) {
            glm::dvec3 d = glm::dvec3(samples_.position(set, int(g.first) + std::countr_zero(visible))) - p;
            double dist2 = glm::dot(d, d);
            if (!(dist2 > 0)) continue;
            glm::dvec3 w = d / std::sqrt(dist2);
            double cosReceiver = std::max(0.0, glm::dot(n, w));
            double cosEmitter = planar ? std::max(0.0, -glm::dot(light.normal, w)) : 1.0;
            e += light.weight * (cosReceiver * cosEmitter / dist2);
        }
    }
    out.visibility[r] = samples_.sampleCount ? float(1.0 - double(blocked) / samples_.sampleCount) : 1.f;
    out.irradiance[r] = glm::vec3(e);
}

}  // namespace penumbra
