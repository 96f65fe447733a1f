#pragma once
/// @file GltfModel.h
/// @brief The validated pieces of glTF loading that GltfReader is built from, shared with readers
/// that need more than positions (IndexedMesh.h reads normals and texture coordinates too).
///
/// tinygltf parses the JSON but does not check that offsets stay inside buffers; these functions
/// do, so that code reading accessors through GltfAccessorView never reads out of bounds.

#include <tiny_gltf.h>

#include <glm/mat4x4.hpp>
#include <glm/vec4.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace penumbra {

/// @brief Accessor elements after validation: element i starts at data + i * stride and all
/// count elements lie inside the buffer.
struct GltfAccessorView {
    const unsigned char* data = nullptr;  ///< null when the accessor has no bufferView: all zeros
    size_t stride = 0;
    size_t count = 0;
    int componentType = 0;
    int components = 0;
    bool normalized = false;
    bool sparse = false;
};

/// @brief Loads a .gltf or .glb (told apart by content) with tinygltf, safely: only regular files
/// are read, URIs are never shell-expanded, images are not read, GLB chunk headers are checked.
/// @throw InputError naming @p path for any failure.
void loadGltfModel(const std::string& path, tinygltf::Model& model);

/// @brief Validates every bufferView and accessor of @p model against its buffers.
/// @return one view per accessor, in accessor order.
/// @throw InputError naming @p path and the offending object.
std::vector<GltfAccessorView> checkGltfAccessors(const std::string& path, const tinygltf::Model& model);

/// @brief Element @p i of a scalar unsigned-integer accessor (0 for an accessor without data).
uint32_t readGltfIndex(const GltfAccessorView& view, uint64_t i);

/// @brief Element @p i as floats (up to 4 components; the rest are 0), decoding the integer
/// and normalized forms KHR_mesh_quantization allows.
glm::vec4 readGltfElement(const GltfAccessorView& view, uint64_t i);

/// @brief A node that draws a mesh, with its world matrix.
struct GltfMeshNode {
    int node = 0;
    int mesh = 0;
    glm::dmat4 world{1.0};
};

/// @brief Walks the default scene (else scene 0, else every root node) parent to child,
/// composing node matrices and TRS in double precision.
/// @return the mesh-drawing nodes in depth-first order.
/// @throw InputError naming @p path for bad references, non-finite transforms or a node reached
///        twice (cycles and shared children).
std::vector<GltfMeshNode> walkGltfScene(const std::string& path, const tinygltf::Model& model);

}  // namespace penumbra
