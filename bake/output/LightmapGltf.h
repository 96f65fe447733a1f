#pragma once
/// @file LightmapGltf.h
/// @brief The meshes of a generated lightmap atlas as a glTF file, with the atlas coordinates as
/// TEXCOORD_1, so that an engine can apply the baked lightmap to them.
///
/// One node and one mesh per atlas mesh, in world space (the scene's transform already applied,
/// so the file lines up with the baked scene as it is), with POSITION, NORMAL, TEXCOORD_0 (the
/// source's, or the atlas coordinates again when it had none: glTF sets start at 0),
/// TEXCOORD_1 and 32-bit indices. The lightmap's file name is recorded in the
/// asset's extras ("penumbra": {"lightmap": NAME}); glTF has no standard lightmap slot.

#include "stream/IndexedMesh.h"

#include <span>
#include <string>

namespace penumbra {

/// @brief Writes @p meshes (each with uv1) to @p path (.glb binary, else .gltf with the buffer
/// embedded), atomically.
/// @param lightmap the lightmap texture's file name, for the extras
/// @throw InputError naming @p path when it cannot be written.
void writeLightmapGltf(const std::string& path, std::span<const IndexedMesh> meshes, const std::string& lightmap);

}  // namespace penumbra
