#pragma once
/// @file GltfDocument.h
/// @brief The JSON half of a glTF 2.0 file (.gltf or .glb), parsed and validated, without a single
/// byte of its buffers.
///
/// Only the document stays resident: buffers, views, accessors, meshes, nodes and the scene, as
/// small value types. Buffer bytes are read window by window later (GltfBytes.h); nothing here
/// loads a buffer, and a .glb's BIN chunk is only located (its offset and length in the file).
///
/// Validation happens here, once, for every reader of glTF (blockers, receiver meshes, the
/// vertex-colour writer): every buffer view lies inside its buffer, every accessor inside its
/// view (with overflow-checked arithmetic), strides hold their elements, references point at
/// existing objects, transforms are finite. Index values and positions are checked where they
/// are read (GltfPrimitive.h), because reading them is exactly what this file avoids.
///
/// Embedded `data:` URIs are base64 text inside the JSON; they are decoded when the document is
/// loaded, and refused above kMaxDataUriBytes (decoded) with an error naming the buffer, because
/// their bytes must stay resident (the JSON text they came in is not kept).
///
/// Sparse accessors are parsed here and read through GltfElements.h.
///
/// Extensions understood: KHR_mesh_quantization (integer positions), EXT_mesh_gpu_instancing,
/// EXT_meshopt_compression and KHR_draco_mesh_compression. Any other extension in
/// `extensionsRequired` is an error naming it.

#include "stream/GltfMaterials.h"

#include <glm/mat4x4.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace penumbra {

/// Largest decoded `data:` URI buffer accepted (16 MiB): such bytes cannot be read in windows.
inline constexpr uint64_t kMaxDataUriBytes = 16ull << 20;

// glTF enumerations, as in the specification.
inline constexpr int kGltfByte = 5120, kGltfUnsignedByte = 5121, kGltfShort = 5122, kGltfUnsignedShort = 5123,
                     kGltfUnsignedInt = 5125, kGltfFloat = 5126;
inline constexpr int kGltfPoints = 0, kGltfTriangles = 4, kGltfTriangleStrip = 5, kGltfTriangleFan = 6;

/// Where a buffer's bytes are.
struct GltfBuffer {
    enum class Source { GlbChunk, File, DataUri, None };
    Source source = Source::None;
    std::string file;         ///< the .glb itself or the external file (GlbChunk, File)
    uint64_t fileOffset = 0;  ///< where byte 0 of the buffer is in @ref file
    uint64_t byteLength = 0;
    std::vector<uint8_t> bytes;  ///< DataUri only: the decoded bytes
};

/// EXT_meshopt_compression on a buffer view: the view's bytes are decoded from these.
struct GltfMeshoptView {
    int buffer = 0;
    uint64_t byteOffset = 0, byteLength = 0;
    uint32_t byteStride = 0;
    uint64_t count = 0;
    enum class Mode { Attributes, Triangles, Indices } mode = Mode::Attributes;
    enum class Filter { None, Octahedral, Quaternion, Exponential } filter = Filter::None;
};

struct GltfBufferView {
    int buffer = 0;
    uint64_t byteOffset = 0, byteLength = 0;
    uint32_t byteStride = 0;  ///< 0: tightly packed
    std::optional<GltfMeshoptView> meshopt;
};

/// Sparse storage of an accessor (glTF 2.0, "Sparse Accessors"): element indices[j] takes the
/// value values[j]; every other element comes from the accessor's bufferView, or is zero without
/// one. Both arrays are tightly packed, and lie inside their views (checked when parsed); the
/// indices' order and range are checked where they are read (GltfPrimitive.h).
struct GltfSparse {
    uint64_t count = 0;
    int indicesView = -1;
    uint64_t indicesOffset = 0;
    int indexType = kGltfUnsignedInt;  ///< UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT
    int valuesView = -1;
    uint64_t valuesOffset = 0;
};

/// An accessor after validation: element i occupies [byteOffset + i * stride, + elementBytes)
/// of its buffer view, and every element lies inside it.
struct GltfAccessor {
    int bufferView = -1;  ///< -1: no data (all zeros, or Draco-decoded)
    uint64_t byteOffset = 0;
    int componentType = kGltfFloat;
    int components = 1;
    bool normalized = false;
    std::optional<GltfSparse> sparse;
    uint64_t count = 0;
    uint32_t stride = 0;
    uint32_t elementBytes = 0;
};

/// KHR_draco_mesh_compression on a primitive.
struct GltfDraco {
    int bufferView = 0;
    std::vector<std::pair<std::string, int>> attributes;  ///< glTF attribute name -> Draco attribute id
};

struct GltfPrimitiveDesc {
    std::vector<std::pair<std::string, int>> attributes;  ///< name -> accessor
    int indices = -1;
    int mode = kGltfTriangles;
    int material = -1;  ///< -1: the default material (opaque)
    std::optional<GltfDraco> draco;

    /// The accessor of attribute @p name, or -1.
    int attribute(const std::string& name) const;
};

struct GltfMeshDesc {
    std::string name;
    std::vector<GltfPrimitiveDesc> primitives;
};

struct GltfNodeDesc {
    std::string name;
    int mesh = -1;
    std::vector<int> children;
    glm::dmat4 local{1.0};
    /// Both a matrix and a translation, rotation or scale other than the defaults (glTF 2.0 allows
    /// one or the other): the matrix is used, as viewers do, and the file is warned of.
    bool matrixOverTrs = false;
    /// EXT_mesh_gpu_instancing accessors (-1 when absent).
    int instanceTranslation = -1, instanceRotation = -1, instanceScale = -1;
    bool instanced() const { return instanceTranslation >= 0 || instanceRotation >= 0 || instanceScale >= 0; }
};

/// @brief A validated glTF document (everything but the buffer bytes).
struct GltfDocument {
    std::string path;
    uint64_t jsonBytes = 0;  ///< the JSON text's length (parsed, then dropped)
    /// KHR_mesh_quantization is declared (extensionsUsed or extensionsRequired): POSITION and NORMAL
    /// may then be integers; without it glTF 2.0 requires them FLOAT.
    bool meshQuantization = false;
    std::vector<GltfBuffer> buffers;
    std::vector<GltfBufferView> views;
    std::vector<GltfAccessor> accessors;
    std::vector<GltfMeshDesc> meshes;
    std::vector<GltfNodeDesc> nodes;
    GltfMaterialTables materials;  ///< materials, textures, images, samplers (GltfMaterials.h)
    std::vector<int> roots;  ///< root nodes of the scene to draw (default, else 0, else every root)
    /// Per material: the alpha id its triangles carry (0: opaque; translucent ids: GltfMaterials.h).
    std::vector<uint32_t> materialAlphaIds;

    /// The alpha id of primitive @p primitive of mesh @p mesh's triangles.
    uint32_t alphaIdOf(int mesh, int primitive) const {
        const int m = meshes[size_t(mesh)].primitives[size_t(primitive)].material;
        return m < 0 ? 0u : materialAlphaIds[size_t(m)];
    }

    /// Heap bytes this document holds (compact tables and decoded data URIs), for memory plans.
    uint64_t residentBytes() const;
};

/// @brief Reads and validates the JSON of @p path (told apart by content: "glTF" magic or JSON).
/// @throw InputError naming @p path and the offending object, e.g. `box.gltf: accessor 3 reads
///        past the end of bufferView 1 (needs 480 bytes, has 240)`; JSON syntax errors give the
///        parser's one-line message.
/// @brief The length of @p path's JSON text without reading it: a GLB's JSON chunk (from its
/// header), else the file's size; 0 when the file cannot be read (loading says why).
uint64_t gltfJsonTextBytes(const std::string& path);

/// @brief How many JSON objects @p path's glTF JSON holds (nodes, accessors, primitives, ...),
/// from one pass over its text, which is read and dropped: the parse's structures that stay grow
/// with them, not with the bytes. 0 when the file cannot be read (loading says why).
uint64_t gltfJsonObjectCount(const std::string& path);

GltfDocument loadGltfDocument(const std::string& path);

/// Bytes of one component of @p componentType (0 for an invalid type).
int gltfComponentBytes(int componentType);

/// @brief A node that draws a mesh, with its world matrix.
struct GltfMeshNode {
    int node = 0;
    int mesh = 0;
    glm::dmat4 world{1.0};
};

/// @brief Walks the document's scene parent to child, composing node matrices in double.
/// @return the mesh-drawing nodes in depth-first order.
/// @throw InputError for a node reached twice (cycles and shared children).
std::vector<GltfMeshNode> walkGltfScene(const GltfDocument& doc);

}  // namespace penumbra
