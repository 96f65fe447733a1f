#pragma once
/// @file GltfBuffers.h
/// @brief Adding data to a glTF model that is being written (a baked copy, the lightmap atlas's
/// meshes): each array becomes a bufferView in buffer 0, 4-byte aligned as float and index
/// accessors require, and an accessor over it.

#include <tiny_gltf.h>

#include <cstddef>

namespace penumbra {

/// @brief Appends @p size bytes to buffer 0 (made if the model has none) as a new bufferView
/// with @p target, and an accessor of @p count elements over it.
/// @return the accessor's index.
int appendGltfAccessor(tinygltf::Model& model, const void* bytes, size_t size, int componentType, int type, size_t count,
                       int target);

}  // namespace penumbra
