#pragma once
/// @file CameraOutput.h
/// @brief What a camera bake writes: a multi-channel OpenEXR and a shaded PNG preview.

#include "bake/output/ImageWriters.h"
#include "bake/light/Light.h"
#include "bake/Scene.h"
#include "bake/shading/ReceiverShading.h"
#include "bake/shading/SmoothShading.h"
#include "receivers/ReceiverSet.h"

#include <span>
#include <vector>

namespace penumbra {

/// @brief The PNG preview path that goes with an output path: "out/a.exr" -> "out/a.png".
std::string previewPath(const std::string& output);

/// @brief The EXR header attributes describing the lights and sample settings
/// ("penumbra:light0" = "type=rect samples=256 ...", "penumbra:samples", ...).
std::vector<ExrAttribute> cameraAttributes(const SceneDesc& scene, const LightSamples& samples);

/// @brief Antialiasing refinement for the outputs: receivers from index `firstPass` on are
/// sub-pixel receivers (grouped by pixel), `subPixels` per refined pixel at most.
struct CameraRefinement {
    size_t firstPass = SIZE_MAX;
    int subPixels = 1;
};

/// @brief Writes @p output (EXR: V, E.R/E.G/E.B, Z, N.X/N.Y/N.Z, A) and its PNG preview, both in
/// strips of 64 rows (ExrStripWriter, PngStripWriter), so no full-frame array is ever held.
/// Pixels without a receiver have A = 0 and V = 0. A refined pixel's V and E (total and per
/// light) are the mean over its covered sub-pixel receivers, A is the covered fraction of its
/// sub-pixels, and Z and N stay the pixel centre's (the first covered sub-pixel's where the
/// centre saw nothing).
/// @param smooth when given, the preview's irradiance uses smooth coherent shading (SmoothShading.h);
/// the EXR's E channels always hold the plain Heckbert-Herf irradiance.
void writeCameraOutputs(const SceneDesc& scene, const ReceiverSet& receivers, const LightSamples& samples,
                        const ReceiverResults& results, const std::string& output, const VertexBend* smooth = nullptr,
                        const CameraRefinement& refinement = {});

/// @brief Bytes writeCameraOutputs() holds for a @p width wide image with @p layers depth layers and
/// @p lights lights: per receiver (its pixel order) and per strip of rows, never per pixel of the
/// whole frame.
uint64_t cameraOutputBytes(int width, int layers, int lights, uint64_t receivers);

/// @brief The irradiance a shaded preview shows for receiver @p r: the baked irradiance, or with
/// @p smooth each light's irradiance scaled by its smooth-shading factor.
glm::vec3 shadedIrradiance(const ReceiverSet& receivers, const ReceiverResults& results, size_t r,
                           const VertexBend* smooth);

}  // namespace penumbra
