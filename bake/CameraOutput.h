#pragma once
/// @file CameraOutput.h
/// @brief What a camera bake writes: a multi-channel OpenEXR and a shaded PNG preview.

#include "bake/Light.h"
#include "bake/Scene.h"
#include "bake/ReceiverShading.h"
#include "receivers/ReceiverSet.h"

#include <span>
#include <vector>

namespace penumbra {

/// @brief The PNG preview path that goes with an output path: "out/a.exr" -> "out/a.png".
std::string previewPath(const std::string& output);

/// @brief Writes @p output (EXR: V, E.R/E.G/E.B, Z, N.X/N.Y/N.Z, A) and its PNG preview.
/// Pixels without a receiver have A = 0 and V = 0.
void writeCameraOutputs(const SceneDesc& scene, const ReceiverSet& receivers, const LightSamples& samples,
                        const ReceiverResults& results, const std::string& output);

}  // namespace penumbra
