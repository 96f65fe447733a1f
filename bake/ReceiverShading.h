#pragma once
/// @file ReceiverShading.h
/// @brief Turns one receiver's mask into what the outputs need: the visible fraction of the light
/// and the irradiance (Heckbert & Herf 1997, Eq. 2). Done as each receiver's result becomes final,
/// so a bake never has to hold every receiver's mask at once.

#include "bake/Light.h"
#include "receivers/ReceiverSet.h"

#include <glm/vec3.hpp>

#include <span>
#include <vector>

namespace penumbra {

/// @brief Per-receiver results of a bake.
struct ReceiverResults {
    std::vector<float> visibility;       ///< unblocked samples / K, all lights together
    std::vector<glm::vec3> irradiance;   ///< RGB, W/m^2 for radiance in W/(m^2 sr)
};

class ReceiverShader {
public:
    ReceiverShader(const std::vector<LightDesc>& lights, const LightSamples& samples, const ReceiverSet& receivers,
                   std::span<const uint32_t> sampleSets);

    /// @brief Visible fraction and irradiance of receiver @p r.
    /// @param groupWords one word per group (bit set = blocked), or nullptr when nothing is blocked
    /// @param fullUmbra every sample blocked (groupWords is ignored)
    void shade(uint32_t r, const uint64_t* groupWords, bool fullUmbra, ReceiverResults& out) const;

private:
    struct PerLight {
        glm::dvec3 normal;  ///< emitting side; zero for volumetric lights (no emitter cosine)
        glm::dvec3 weight;  ///< radiance x area per sample
    };
    const LightSamples& samples_;
    const ReceiverSet& receivers_;
    std::span<const uint32_t> sets_;
    std::vector<PerLight> lights_;
};

}  // namespace penumbra
