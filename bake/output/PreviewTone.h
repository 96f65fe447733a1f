#pragma once
/// @file PreviewTone.h
/// @brief The tone mapping of every 8-bit preview (camera and vertex bakes): a little ambient
/// light on white Lambert surfaces, an exposure that puts the brighter lit surfaces near white,
/// and the sRGB transfer function (encodeSrgb()).

#include <glm/vec3.hpp>

#include <vector>

namespace penumbra {

/// @brief Maps linear irradiance to the linear colour a preview shows.
struct PreviewTone {
    static constexpr float kAmbient = 0.06f;     ///< so fully shadowed surfaces keep their shape
    static constexpr float kBackground = 0.02f;  ///< pixels without a surface: a neutral dark grey
    float exposure = 1.f;

    /// The colour of a surface receiving @p irradiance (linear; encodeSrgb() each channel).
    glm::vec3 operator()(const glm::vec3& irradiance) const { return glm::vec3(kAmbient) + exposure * irradiance; }
};

/// @brief Rec. 709 luminance of linear @p rgb.
inline float previewLuminance(const glm::vec3& rgb) { return 0.2126f * rgb.x + 0.7152f * rgb.y + 0.0722f * rgb.z; }

/// @brief The tone whose exposure maps the 99th percentile of @p luminance to 0.92: a few
/// specular-bright receivers do not darken the whole preview. Empty or all-dark input: exposure 0.92.
/// @param luminance reordered in place (nth_element).
PreviewTone previewTone(std::vector<float>& luminance);

}  // namespace penumbra
