#pragma once
/// @file ExrMetadata.h
/// @brief The header attributes of penumbra's EXRs: the standard ones compositors read
/// (software, capDate, utcOffset, worldToCamera, worldToNDC) and the bake's settings, each with
/// its own type (int, float, v3f, float vector), never numbers in strings.

#include "bake/output/ExrSettings.h"
#include "bake/output/ImageWriters.h"
#include "bake/light/Light.h"
#include "receivers/CameraReceivers.h"

#include <vector>

namespace penumbra {

struct SceneDesc;

/// @brief The attributes every bake's EXR carries:
/// - `software` ("penumbra VERSION"); `capDate` ("YYYY:MM:DD HH:MM:SS", UTC) with `utcOffset` 0:
///   the time in SOURCE_DATE_EPOCH when it is set, else the scene file's modification time, so
///   that baking the same scene twice gives the same bytes (absent when neither is known);
/// - `penumbra:lights`, `penumbra:samples`, `penumbra:sampleSets`, `penumbra:groupSize` (int),
///   `penumbra:seed` (int; a string when above 2^31 - 1), `penumbra:epsilon` (float),
///   `penumbra:rgb` ("irradiance" or "visibility": what R, G, B hold);
/// - per light i, `penumbra:light<i>.type` (string), `.samples`, `.sampleSets` (int) and its
///   shape: `.center` (v3f; a polygon's area centroid), `.u`/`.v` (rect), `.normal`/`.radius`
///   (disk), `.radius` (sphere), `.vertices` (polygon: x, y, z per vertex, a float vector),
///   `.area` (float) and `.radiance` (v3f); a sun has `.direction`, `.angularDiameterDeg` and
///   `.irradiance`.
std::vector<ExrAttribute> bakeAttributes(const SceneDesc& scene, const LightSamples& samples, ExrColour colour);

/// @brief OpenEXR's `worldToCamera`: world to the camera space of the standard, left-handed with
/// x right, y up and z along the view direction (points in front have z > 0), as a row-vector
/// matrix (p' = (p, 1) * m).
ExrMatrix worldToCameraMatrix(const CameraDesc& camera);

/// @brief OpenEXR's `worldToNDC`: world to the image plane, (0, 0) at the top-left corner of the
/// display window and (1, 1) at the bottom-right; divide x and y by w after the product.
ExrMatrix worldToNdcMatrix(const CameraDesc& camera);

/// @brief `worldToCamera` and `worldToNDC` as attributes.
std::vector<ExrAttribute> cameraAttributes(const CameraDesc& camera);

}  // namespace penumbra
