#pragma once
/// @file VolumeSlice.h
/// @brief `penumbra vdb-slice`: a PNG of one slice of a grid in a .vdb file. OpenVDB is in the
/// volume plugin (bake/volume), which registers the writer when it loads; this entry point loads
/// the plugin on first use, so the CLI maps OpenVDB only when it reads or writes a VDB.

#include <string>

namespace penumbra {

using VolumeSliceWriter = void (*)(const std::string& vdbPath, const std::string& pngPath, const std::string& gridName,
                                   char axis, double at, int minWidth);

/// @brief Called by the volume plugin as it loads.
void registerVolumeSliceWriter(VolumeSliceWriter writer);

/// @brief Renders an axis-aligned slice of a float grid of a .vdb file as an 8-bit grey PNG
/// (sRGB-encoded value, clamped to [0,1]), nearest-neighbour upscaled to at least @p minWidth px.
/// @param axis 'x', 'y' or 'z': the slice is the plane axis = @p at (world units), at the
///        nearest voxel centre. Image right/up: (z, y) for x, (x, y) for z; for y, x right and z down
///        (seen from above).
/// @throw InputError naming the file for a missing grid, a bad axis or a slice outside the grid,
/// or when the volume plugin is not installed.
void writeVolumeSlicePng(const std::string& vdbPath, const std::string& pngPath, const std::string& gridName,
                         char axis, double at, int minWidth = 512);

}  // namespace penumbra
