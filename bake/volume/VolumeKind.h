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
/// maps voxel (i,j,k) to its receiver's centre, a fog volume: every baked voxel is active and the
/// background 0 means "not baked" (docs/scene-format.md#volume). Exactly constant regions, lit or
/// umbra, prune to active tiles (tolerance 0). With `"irradiance": true` a Vec3SGrid
/// `irradiance` (W/m^2, background 0) is written too.
/// The receiver region's index bounds are stored as grid metadata `penumbra_min`/`penumbra_max`.
///
/// VolumeKind.cpp and bake/output/OpenVdb.cpp are the only files that include OpenVDB (it
/// compiles slowly). The kind registers itself (ReceiverKind.h); nothing includes this header.
