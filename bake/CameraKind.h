#pragma once
/// @file CameraKind.h
/// @brief The "camera" receiver kind: a z-buffer pass over the scene stream makes one receiver
/// per covered pixel; it writes a multi-channel EXR and a shaded PNG preview (CameraOutput.h).

#include "bake/ReceiverKind.h"

#include <memory>

namespace penumbra {

/// @brief Makes the camera kind from its "receivers" object (eye, target, up, fov_deg, width,
/// height) and the scene (lights and bake.smooth_shading, for the preview).
/// @throw InputError naming the key for a bad camera.
std::unique_ptr<ReceiverKind> makeCameraKind(const JsonParams& params, const SceneDesc& scene);

}  // namespace penumbra
