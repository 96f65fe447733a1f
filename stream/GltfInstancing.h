#pragma once
/// @file GltfInstancing.h
/// @brief A node's EXT_mesh_gpu_instancing: its accessors, checked once, and each instance's
/// transform. The blocker stream (GltfReader.cpp) and the receiver meshes (IndexedMesh.cpp, which
/// also feeds `convert` to glTF) place instances the same way, so a vertex or lightmap bake gets
/// receivers on every instance the blockers have, with the same bits.

#include "stream/GltfBytes.h"
#include "stream/GltfDocument.h"

#include <glm/mat4x4.hpp>

#include <cstdint>

namespace penumbra {

/// A node's instancing accessors (-1: absent) and instance count (1 for a node without them).
struct GltfInstancing {
    int translation = -1, rotation = -1, scale = -1;
    uint64_t instances = 1;
    bool any() const { return translation >= 0 || rotation >= 0 || scale >= 0; }
};

/// @brief The instancing of node @p index of @p doc.
/// @throw InputError "FILE: node N EXT_mesh_gpu_instancing: ..." for an accessor of the wrong
/// type, sparse or without a bufferView, of UNSIGNED_INT components, or of another length.
GltfInstancing gltfInstancingOf(const GltfDocument& doc, int index);

/// @brief T * R * S of instance @p i (the identity for a node without instancing), applied
/// before the node's own transform.
/// @throw InputError "FILE: node N EXT_mesh_gpu_instancing: instance I has a non-finite transform"
glm::dmat4 gltfInstanceLocal(const GltfDocument& doc, GltfBytes& bytes, const GltfInstancing& instancing, int node,
                             uint64_t i);

}  // namespace penumbra
