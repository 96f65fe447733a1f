#pragma once
/// @file TinyGltfLoad.h
/// @brief Loading a whole glTF model with tinygltf, safely, for the one reader that needs every
/// JSON object and buffer byte: the vertex-colour writer, which writes a copy of the file with
/// attributes added (bake/VertexColorKind.cpp). Geometry is read through GltfDocument.h and
/// GltfPrimitive.h instead, which never load a whole buffer.
///
/// Safe means: only regular files are read, URIs are never shell-expanded (tinygltf's default
/// runs them through wordexp), images are not read, and GLB chunk headers are checked before
/// tinygltf, which trusts some of those lengths, sees them.

#include <tiny_gltf.h>

#include <string>

namespace penumbra {

/// @brief Loads @p path (.gltf or .glb, told apart by content) into @p model.
/// @throw InputError naming @p path, with tinygltf's first error line when it fails.
void loadTinyGltf(const std::string& path, tinygltf::Model& model);

}  // namespace penumbra
