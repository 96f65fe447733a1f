#pragma once
/// @file CameraKind.h
/// @brief The "camera" receiver kind: a z-buffer pass over the scene stream makes one receiver
/// per covered pixel; it writes a multi-channel EXR and a shaded PNG preview (CameraOutput.h).

#include "bake/kinds/ReceiverKind.h"
#include "receivers/CameraReceivers.h"

#include <memory>
#include <span>
#include <vector>

namespace penumbra {

/// @brief The camera's "antialias" object: two-pass adaptive antialiasing. samples == 0: off.
struct CameraAntialias {
    double threshold = 0.1;  ///< a pixel is refined when |V - V_neighbour| exceeds this
    int samples = 0;         ///< sub-pixel receivers per refined pixel (n x n, a square)
};

/// @brief The pixels (layer 0, ascending y * width + x) whose first-pass visible fraction differs
/// from one of their 8 neighbours' by more than @p threshold, or where one of the two has a
/// surface and the other none. Receivers from @p firstPass on are ignored.
std::vector<uint32_t> highContrastPixels(const ReceiverSet& receivers, std::span<const float> visibility, size_t firstPass,
                                         double threshold);

/// @brief Reads a camera's view from @p j: eye, target (required), up, fov_deg, width and height
/// (the camera kind's keys; a vertex bake's preview camera takes the same). Not validated.
/// @throw InputError naming the key for a value of the wrong type or out of range.
CameraDesc readCameraView(const JsonParams& j);

/// @brief Makes the camera kind from its "receivers" object (eye, target, up, fov_deg, width,
/// height) and the scene (lights and bake.smooth_shading, for the preview); null for
/// KindUse::Validate.
/// @throw InputError naming the key for a bad camera.
std::unique_ptr<ReceiverKind> makeCameraKind(const JsonParams& params, const SceneDesc& scene, KindUse use);

}  // namespace penumbra
