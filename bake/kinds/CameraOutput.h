#pragma once
/// @file CameraOutput.h
/// @brief What a camera bake writes: a multi-channel OpenEXR and a shaded PNG preview.

#include "bake/output/ExrSettings.h"
#include "bake/output/ImageWriters.h"
#include "bake/light/Light.h"
#include "bake/Scene.h"
#include "stream/util/Progress.h"
#include "bake/shading/ReceiverShading.h"
#include "bake/shading/SmoothShading.h"
#include "receivers/CameraReceivers.h"
#include "receivers/ReceiverSet.h"

#include <span>
#include <vector>

namespace penumbra {

/// @brief The PNG preview path that goes with an output path: "out/a.exr" -> "out/a.png".
std::string previewPath(const std::string& output);

/// @brief previewPath() as the one file a kind writes beside its output (ReceiverKind.h's
/// DerivedOutputs): the camera's and the vertex colours' preview.
std::vector<std::string> previewOutputs(const std::string& output);

/// @brief Antialiasing refinement for the outputs: receivers from index `firstPass` on are
/// sub-pixel receivers (grouped by pixel), `subPixels` per refined pixel at most.
struct CameraRefinement {
    size_t firstPass = SIZE_MAX;
    int subPixels = 1;
};

/// @brief The EXR channels of a camera bake, in the order the strips fill them. Layer 0:
/// `R`, `G`, `B` (the irradiance, or with ExrColour::Visibility the visible fraction as grey),
/// `A` (coverage), `visibility.V`, `depth.Z` (kept FLOAT in half files), `normal.X/Y/Z`, and with
/// ExrColour::Visibility `irradiance.R/G/B`. Deeper layer k: the same passes under `layer<k>.`,
/// its colour as `layer<k>.Combined.R/G/B/A` (Blender's name for a layer's main pass, so every
/// layer groups as one). With several lights: `light<i>.visibility.V` and
/// `light<i>.irradiance.R/G/B` per light (of the nearest surface).
std::vector<ExrChannelSpec> cameraChannels(int layers, int lights, ExrColour colour);

/// @brief Writes @p output (the EXR of cameraChannels(), with scene.exr's format) and its PNG
/// preview, both in strips of 64 rows (ExrStripWriter, PngStripWriter), so no full-frame array is
/// ever held. Pixels without a receiver have A = 0, V = 0 and depth +infinity. `depth.Z` is
/// camera-space depth along the view axis (OpenEXR's and Nuke's convention; not the distance
/// from the eye), `normal` the world-space normal facing the camera. A refined pixel's V and E
/// (total and per light) are the mean over its covered sub-pixel receivers, A is the covered
/// fraction of its sub-pixels, and Z and N stay the pixel centre's (the first covered
/// sub-pixel's where the centre saw nothing). The header has bakeAttributes() and the camera's
/// `worldToCamera` and `worldToNDC` (ExrMetadata.h).
/// @param smooth when given, the preview's irradiance uses smooth coherent shading (SmoothShading.h);
/// the EXR always holds the plain Heckbert-Herf irradiance.
/// @param progress when given, told each strip's rows as they are written (the image's height in all)
void writeCameraOutputs(const SceneDesc& scene, const CameraDesc& camera, const ReceiverSet& receivers,
                        const LightSamples& samples, const ReceiverResults& results, const std::string& output,
                        const VertexBend* smooth = nullptr, const CameraRefinement& refinement = {},
                        ProgressReporter* progress = nullptr);

/// @brief Bytes writeCameraOutputs() holds for a @p width wide image with @p layers depth layers and
/// @p lights lights: per receiver (its pixel order) and per strip of rows, never per pixel of the
/// whole frame.
uint64_t cameraOutputBytes(int width, int layers, int lights, uint64_t receivers, const ExrSettings& exr);

/// @brief The irradiance a shaded preview shows for receiver @p r: the baked irradiance, or with
/// @p smooth each light's irradiance scaled by its smooth-shading factor.
glm::vec3 shadedIrradiance(const ReceiverSet& receivers, const ReceiverResults& results, size_t r,
                           const VertexBend* smooth);

}  // namespace penumbra
