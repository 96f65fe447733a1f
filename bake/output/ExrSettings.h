#pragma once
/// @file ExrSettings.h
/// @brief The scene's "exr" object: how camera and lightmap EXRs are stored (FLOAT or HALF,
/// scanlines or tiles) and what their R, G, B channels hold.

#include "bake/output/ImageWriters.h"
#include "stream/util/JsonParams.h"

#include <string>

namespace penumbra {

/// What the default layer's R, G, B hold (A is always the coverage).
enum class ExrColour {
    Irradiance,  ///< the irradiance, W/m^2 (the default)
    Visibility,  ///< the visible fraction V as grey; the irradiance moves to irradiance.R/G/B
};

/// @brief The "exr" settings of a scene (docs/scene-format.md#exr).
struct ExrSettings {
    ExrFormat format;                          ///< pixel type and tiling
    ExrColour colour = ExrColour::Irradiance;  ///< "rgb"
};

/// @brief Reads the "exr" object: {"pixel_type": "float"|"half", "tile_size": 0|16..1024,
/// "compression": "zip"|..., "zip_level": 1..9, "rgb": "irradiance"|"visibility"}.
/// @throw InputError naming the key for a bad value or an unknown key.
ExrSettings parseExrSettings(const JsonParams& j);

/// @brief "float" or "half" (exr.pixel_type, --exr-pixel-type) as ExrFormat::half.
/// @throw InputError naming @p where for anything else.
bool parseExrPixelType(const std::string& value, const std::string& where);

/// @brief "none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa" or "dwab"
/// (exr.compression), OpenEXR's names in lower case.
/// @throw InputError naming @p where for anything else.
ExrCompression parseExrCompression(const std::string& value, const std::string& where);

/// @brief Checks a tile size (exr.tile_size, --exr-tile-size): 0 (scanlines) or 16..1024.
/// @throw InputError naming @p where when it is out of range.
int checkExrTileSize(int64_t size, const std::string& where);

}  // namespace penumbra
