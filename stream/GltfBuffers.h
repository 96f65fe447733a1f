#pragma once
/// @file GltfBuffers.h
/// @brief Building a glTF model to write (a converted mesh, a baked copy, the lightmap atlas's
/// meshes): each array becomes a bufferView in buffer 0, 4-byte aligned as float and index
/// accessors require, and an accessor over it; a primitive becomes a mesh and a node; the model
/// is written in one atomic step.

#include <tiny_gltf.h>

#include <cstddef>
#include <filesystem>
#include <string>

namespace penumbra {

/// @brief Appends @p size bytes to buffer 0 (made if the model has none) as a new bufferView
/// with @p target, and an accessor of @p count elements over it.
/// @return the accessor's index.
int appendGltfAccessor(tinygltf::Model& model, const void* bytes, size_t size, int componentType, int type, size_t count,
                       int target);

/// @brief Adds @p primitive as a mesh named @p name and a node drawing it.
/// @return the node's index.
int appendGltfMeshNode(tinygltf::Model& model, const std::string& name, tinygltf::Primitive primitive);

/// @brief The file beside the .gltf @p path that holds buffer @p i of @p count external ones:
/// "x.bin" for x.gltf when there is one, "x-0.bin", "x-1.bin"... when there are more.
std::filesystem::path externalBufferPath(const std::string& path, size_t i, size_t count);

/// @brief Encodes @p model (binary .glb when @p binary, else .gltf with its buffers as data URIs,
/// or, above kMaxDataUriBytes, as "STEM.bin" files beside it) and writes it to @p path
/// atomically, the .bin files first (removed again if the .gltf cannot be written).
/// @param keepImageUris images keep their URIs as they are (a copy referring to the originals).
/// @throw InputError naming @p path when tinygltf cannot encode the model or a write fails.
void writeGltfModel(tinygltf::Model& model, const std::string& path, bool binary, bool keepImageUris = false);

}  // namespace penumbra
