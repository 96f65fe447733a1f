#pragma once
/// @file GltfPrimitive.h
/// @brief The one validated walker over glTF triangle primitives, used by every reader of glTF
/// geometry: the blocker stream (GltfReader.h), the receiver meshes (IndexedMesh.h) and the
/// vertex-colour writer (bake/VertexColorKind.cpp).
///
/// gltfTrianglePrimitive() does the per-primitive checks once (POSITION present, VEC3, an allowed
/// component type, dense or sparse storage (GltfElements.h); indices a SCALAR of unsigned integers; TRIANGLES counts a
/// multiple of 3). GltfPrimitiveReader then hands out triangles as vertex indices (the strip and
/// fan corner rule lives in gltfTriangleCorners(), nowhere else), checking each index against the
/// vertex count and each position for finiteness as it is read, through the windowed bytes of
/// GltfBytes.h. Compressed primitives read the same way: EXT_meshopt_compression views are decoded
/// by GltfBytes, KHR_draco_mesh_compression primitives are decoded whole when the reader is made.

#include "stream/GltfBytes.h"
#include "stream/GltfDocument.h"
#include "stream/GltfElements.h"

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace penumbra {

/// @brief A primitive that draws triangles, after its checks.
struct GltfPrimitiveLayout {
    int mesh = 0, primitive = 0;
    int positions = -1;  ///< POSITION accessor
    int indices = -1;    ///< indices accessor, or -1
    int mode = kGltfTriangles;
    uint64_t vertices = 0;   ///< POSITION elements
    uint64_t triangles = 0;
    bool draco = false;
    /// Bytes that must be resident to read it: decoded meshopt views, or the decoded Draco mesh,
    /// and the sparse accessors' index lists (@ref sparseBytes of it).
    uint64_t decodeBytes = 0;
    uint64_t sparseBytes = 0;

    /// Whether it is stored compressed (Draco or meshopt), so that a copy cannot be extended.
    bool compressed() const { return draco || decodeBytes > sparseBytes; }

    /// "FILE: mesh M primitive P", the prefix of every message about it.
    std::string where(const GltfDocument& doc) const;
};

/// Primitives skipped because they draw no triangles, for one warning per kind.
struct GltfSkipped {
    std::map<int, size_t> modes;  ///< mode -> primitives
    size_t withoutPositions = 0;
    /// Prints the warnings (one line per mode) to stderr.
    void warn(const std::string& path) const;
};

/// @brief Checks primitive @p p of mesh @p m.
/// @return the layout, or nothing for points, lines and primitives without POSITION (counted in
///         @p skipped when given).
/// @throw InputError "FILE: mesh M primitive P: ..." for malformed primitives.
std::optional<GltfPrimitiveLayout> gltfTrianglePrimitive(const GltfDocument& doc, int m, int p, GltfSkipped* skipped = nullptr);

/// @brief Positions in the drawing sequence of the corners of triangle @p t: TRIANGLES take
/// (3t, 3t+1, 3t+2); strips alternate winding, (t, t+1, t+2) then (t, t+2, t+1); fans pivot on
/// the first vertex, (t+1, t+2, 0).
std::array<uint64_t, 3> gltfTriangleCorners(int mode, uint64_t t);

/// @brief Decodes an element of @p accessor from its bytes (up to 4 components, the rest 0),
/// including the integer and normalized forms of KHR_mesh_quantization.
glm::vec4 decodeGltfElement(const uint8_t* bytes, const GltfAccessor& accessor);

struct DracoPrimitive;

/// @brief Reads one primitive's triangles and vertex attributes.
class GltfPrimitiveReader {
public:
    /// @param attributes decode every attribute of a Draco primitive (receivers), not just POSITION.
    /// @throw InputError when a Draco primitive does not decode or disagrees with its accessors.
    GltfPrimitiveReader(const GltfDocument& doc, GltfBytes& bytes, const GltfPrimitiveLayout& layout, bool attributes = false);
    ~GltfPrimitiveReader();

    const GltfPrimitiveLayout& layout() const { return layout_; }

    /// @brief Vertex indices of triangle @p t (< layout().triangles), each checked against the
    /// vertex count. @throw InputError naming the index accessor and element.
    std::array<uint32_t, 3> triangle(uint64_t t);

    /// @brief Position of vertex @p v. @throw InputError when it is not finite.
    glm::vec3 position(uint64_t v);

    /// @brief Element @p v of attribute @p name (NORMAL, TEXCOORD_0, ...): checked to be an
    /// accessor with one element per vertex and @p components components. @throw InputError
    /// when it is missing or malformed; use has() first.
    glm::vec4 attribute(const std::string& name, int components, uint64_t v);
    bool has(const std::string& name) const;

private:
    uint32_t sequence(uint64_t i);
    /// The checked reader of attribute @p name, made on its first read.
    GltfElements& checkedAttribute(const std::string& name, int components);

    const GltfDocument& doc_;
    GltfBytes& bytes_;
    GltfPrimitiveLayout layout_;
    const GltfPrimitiveDesc& desc_;
    std::unique_ptr<DracoPrimitive> draco_;
    std::optional<GltfElements> positions_, indices_;  // empty for Draco primitives
    std::vector<std::pair<int, GltfElements>> attributes_;  // accessor -> reader, as read
};

/// @brief Bytes the Draco decoder needs for a primitive of @p vertices and @p indices (decoded
/// mesh plus the decoder's own tables), for memory plans.
uint64_t dracoDecodeBytes(uint64_t vertices, uint64_t indices, uint64_t compressedBytes);

}  // namespace penumbra
