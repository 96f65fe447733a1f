#pragma once
/// @file CameraOutput.h
/// @brief What a camera bake writes: a multi-channel OpenEXR and a shaded PNG preview.

#include "bake/Light.h"
#include "bake/Scene.h"
#include "bake/VisibilityMasks.h"
#include "receivers/ReceiverSet.h"

#include <span>
#include <vector>

namespace penumbra {

/// @brief Irradiance at each receiver from its unblocked samples (Heckbert & Herf 1997, Eq. 2):
/// sum over visible samples of radiance x (area / samples) x cos(theta) x cos(theta') / r^2.
/// Volumetric lights use their cross-section as area and no emitter cosine.
std::vector<glm::vec3> irradiance(const std::vector<LightDesc>& lights, const LightSamples& samples,
                                  const ReceiverSet& receivers, std::span<const uint32_t> sampleSets,
                                  const VisibilityMasks& masks);

/// @brief The PNG preview path that goes with an output path: "out/a.exr" -> "out/a.png".
std::string previewPath(const std::string& output);

/// @brief Writes scene.output (EXR: V, E.R/E.G/E.B, Z, N.X/N.Y/N.Z, A) and its PNG preview.
/// Pixels without a receiver have A = 0 and V = 0.
void writeCameraOutputs(const SceneDesc& scene, const ReceiverSet& receivers, const LightSamples& samples,
                        std::span<const uint32_t> sampleSets, const VisibilityMasks& masks,
                        std::span<const float> visibility);

}  // namespace penumbra
