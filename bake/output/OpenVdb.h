#pragma once
/// @file OpenVdb.h
/// @brief What the volume receivers share with `penumbra vdb-slice`: OpenVDB's one-time set-up
/// and the slice preview of a written grid. Only OpenVdb.cpp and bake/kinds/VolumeKind.cpp
/// include OpenVDB itself (it compiles slowly).

#include <string>

namespace penumbra {

/// @brief openvdb::initialize(), once per process, from any thread.
void initializeOpenVdb();

/// @brief Renders an axis-aligned slice of a float grid of a .vdb file as an 8-bit grey PNG
/// (sRGB-encoded value, clamped to [0,1]), nearest-neighbour upscaled to at least @p minWidth px.
/// @param axis 'x', 'y' or 'z': the slice is the plane axis = @p at (world units), at the
///        nearest voxel centre. Image right/up: (z, y) for x, (x, y) for z; for y, x right and z down
///        (seen from above).
/// @throw InputError naming the file for a missing grid, a bad axis or a slice outside the grid.
void writeVolumeSlicePng(const std::string& vdbPath, const std::string& pngPath, const std::string& gridName,
                         char axis, double at, int minWidth = 512);

}  // namespace penumbra
