#pragma once
/// @file VolumeKind.h
/// @brief The "volume" receiver kind: receivers at voxel centres, written as an OpenVDB file.
///
/// Scene: `{"type": "volume", "voxel_size": h, "box": [[x0,y0,z0],[x1,y1,z1]]}` puts receivers at
/// the centres of the voxels tiling the box (the lattice starts at the box's low corner), or
/// `{"type": "volume", "voxel_size": h, "narrow_band": {"geometry": [0], "width": w}}` at every
/// centre of the lattice of multiples of h that lies within w of a triangle of the named
/// geometry entries. Receivers have a zero normal, so irradiance is taken without a receiver
/// cosine (fluence-like; see ReceiverShading.h).
///
/// Output (the scene output, `.vdb`): a FloatGrid `visibility` whose index-to-world transform
/// maps voxel (i,j,k) to its receiver's centre. Its background is 1 (lit): fully lit voxels are
/// stored inactive, so together with fully shadowed (V == 0) regions they collapse into constant
/// tiles (pruned with tolerance 0, only exactly constant regions), and a mostly lit volume stays
/// small. With `"irradiance": true` a Vec3SGrid `irradiance` (W/m^2, background 0) is written too.
/// The receiver region's index bounds are stored as grid metadata `penumbra_min`/`penumbra_max`.
///
/// This file and VolumeKind.cpp are the only ones that include OpenVDB (it compiles slowly).

#include <string>

namespace penumbra {


/// @brief Renders an axis-aligned slice of a float grid of a .vdb file as an 8-bit grey PNG
/// (sRGB-encoded value, clamped to [0,1]), nearest-neighbour upscaled to at least @p minWidth px.
/// @param axis 'x', 'y' or 'z': the slice is the plane axis = @p at (world units), at the
///        nearest voxel centre. Image right/up: (z, y) for x, (x, y) for z; for y, x right and z down
///        (seen from above).
/// @throw InputError naming the file for a missing grid, a bad axis or a slice outside the grid.
void writeVolumeSlicePng(const std::string& vdbPath, const std::string& pngPath, const std::string& gridName,
                         char axis, double at, int minWidth = 512);

}  // namespace penumbra
