#pragma once
/// @file ReceiverShading.h
/// @brief Turns one receiver's mask into what the outputs need: the visible fraction of the light
/// and the irradiance (Heckbert & Herf 1997, Eq. 2). Done as each receiver's result becomes final,
/// so a bake never has to hold every receiver's mask at once.

#include "bake/light/Light.h"
#include "receivers/ReceiverSet.h"

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include <functional>
#include <mutex>
#include <span>
#include <vector>

namespace penumbra {

/// @brief Per-receiver results of a bake.
struct ReceiverResults {
    std::vector<float> visibility;       ///< unblocked samples / K, all lights together
    std::vector<glm::vec3> irradiance;   ///< RGB, W/m^2 for radiance in W/(m^2 sr), all lights summed
    /// With more than one light: each light's own visible fraction and irradiance, receiver-major
    /// (entry r * lights + l). Empty with a single light, where they equal the totals.
    int lights = 1;
    std::vector<float> lightVisibility;
    std::vector<glm::vec3> lightIrradiance;

    /// @brief Sizes the arrays for @p receivers receivers and @p lightCount lights.
    void resize(size_t receivers, int lightCount) {
        lights = lightCount;
        visibility.assign(receivers, 0.f);
        irradiance.assign(receivers, glm::vec3(0.f));
        lightVisibility.assign(lightCount > 1 ? receivers * size_t(lightCount) : 0, 0.f);
        lightIrradiance.assign(lightCount > 1 ? receivers * size_t(lightCount) : 0, glm::vec3(0.f));
    }
    /// @brief Grows the arrays to @p receivers receivers, keeping the results already there.
    void extend(size_t receivers) {
        visibility.resize(receivers, 0.f);
        irradiance.resize(receivers, glm::vec3(0.f));
        if (lights > 1) lightVisibility.resize(receivers * size_t(lights), 0.f), lightIrradiance.resize(receivers * size_t(lights), glm::vec3(0.f));
    }
    float visibilityOf(size_t r, int light) const { return lights > 1 ? lightVisibility[r * lights + light] : visibility[r]; }
    glm::vec3 irradianceOf(size_t r, int light) const {
        return lights > 1 ? lightIrradiance[r * lights + light] : irradiance[r];
    }
};

/// @brief Radiance of a light given by its emitted power (W, RGB): P / (pi A) for one-sided
/// planar emitters (rect, disk, polygon) and P / (4 pi^2 r^2) for a sphere (a Lambertian sphere
/// surface). Throws InputError for a sun (suns take irradiance or radiance).
glm::dvec3 radianceFromPower(const LightDesc& light, const glm::dvec3& power);

class ReceiverShader {
public:
    /// @param lights the lights as sampled (suns placed); their order is the samples' light order.
    ReceiverShader(const std::vector<LightDesc>& lights, const LightSamples& samples, const ReceiverSet& receivers,
                   std::span<const uint32_t> sampleSets);

    /// @brief Visible fraction and irradiance of receiver @p r, in total and per light.
    /// @param groupWords one word per group (bit set = blocked), or nullptr when nothing is blocked
    /// @param fullUmbra every sample blocked (groupWords is ignored)
    /// @param depth per sample, R, G, B optical depth of the translucent blockers crossed
    /// (stream/Translucency.h; sampleCount x 3), or nullptr: none. It scales each visible sample's
    /// irradiance by T = 2^(-d / 2^16) per channel; the visible fraction does not change.
    void shade(uint32_t r, const uint64_t* groupWords, bool fullUmbra, ReceiverResults& out,
               const uint32_t* depth = nullptr) const;

    /// @brief For methods that give a visible fraction per light instead of masks (penumbra-map):
    /// each light's irradiance is its unoccluded irradiance times that fraction. For a rect or
    /// polygon light seen by an oriented receiver the unoccluded irradiance is the exact integral
    /// over the emitter (unoccludedIrradiance), the limit of the sample sum the exact methods take.
    /// @param lightVisibility one value in [0, 1] per light
    /// @param depth as for shade(), or nullptr: each light's irradiance is also scaled, per
    /// channel, by its samples' transmittance weighted by their unoccluded irradiance (the share
    /// the translucent blockers let through); the visible fraction does not change
    /// @param tintSamples the samples that weigh the tint: those not set in these words (one
    /// per group; nullptr: all), the ones @p depth was computed for
    void shadeVisibleFraction(uint32_t r, const float* lightVisibility, ReceiverResults& out,
                              const uint32_t* depth = nullptr, const uint64_t* tintSamples = nullptr) const;

private:
    /// Light @p li's irradiance at receiver @p r from its unblocked samples; @p blocked gets how
    /// many of its samples are blocked.
    glm::dvec3 lightIrradiance(uint32_t r, int li, const uint64_t* groupWords, bool fullUmbra, uint64_t& blocked,
                               const uint32_t* depth = nullptr) const;
    /// The same with every sample visible: for a rect or polygon light and an oriented receiver the
    /// exact integral (Lambert's formula over the emitter clipped to the receiver's hemisphere,
    /// a few operations per corner instead of per sample); otherwise the sample sum, vectorized.
    glm::dvec3 unoccludedIrradiance(uint32_t r, int li) const;

    struct PerLight {
        glm::dvec3 normal;  ///< emitting side; zero for volumetric lights (no emitter cosine)
        glm::dvec3 weight;  ///< radiance x area per sample; for a sun, irradiance per sample
        bool sun = false;   ///< directional: weight x cos(receiver) only, no 1/r^2
        int samples = 1;
        glm::dvec3 radiance{0.0};         ///< planar emitters: the radiance, for the exact integral
        std::vector<glm::dvec3> corners;  ///< rect and polygon lights: the emitter's outline, in order
        bool planar() const { return glm::dot(normal, normal) > 0; }  ///< an emitter cosine applies
    };
    const LightSamples& samples_;
    const ReceiverSet& receivers_;
    std::span<const uint32_t> sets_;
    std::vector<PerLight> lights_;
    /// Whether light @p light's terms at a receiver with normal @p n are summed in lanes
    /// (sampleSum): a planar emitter, not a sun, an oriented receiver.
    static bool sumsInLanes(const PerLight& light, const glm::dvec3& n);
    /// Light @p li's terms at receiver @p r without its weight, over the samples set in
    /// @p visible (bit j: the light's sample j; null: all), four at a time.
    double lightSampleSum(uint32_t r, int li, const uint64_t* visible) const;
    /// The same with each term times its sample's transmittance (@p depth: 3 per sample, all
    /// lights' samples), summed in sample order.
    glm::dvec3 lightTintedSum(uint32_t r, int li, const uint64_t* visible, const uint32_t* depth) const;
    /// Light @p li's sample x coordinates in receiver @p r's set (y and z follow, a set apart).
    const double* lightSamplesX(uint32_t r, int li) const;
    /// The samples as three arrays of double per set (x, then y, then z), made on first use.
    mutable std::vector<double> soa_;
    mutable std::once_flag soaOnce_;
};

/// @brief Calls @p shadeOne(i) for every i in [0, @p count), in parallel, shown as the `[shade]`
/// phase (quiet or not as @p quiet): receivers shaded from masks a cast did not hand over as it
/// went (a merge's first pass, a tile restored from a checkpoint). @p shadeOne is called
/// concurrently for different i.
void shadeEach(size_t count, bool quiet, const std::function<void(size_t)>& shadeOne);

}  // namespace penumbra
