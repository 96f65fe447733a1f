#pragma once
/// @file IndexedMesh.h
/// @brief Indexed triangle meshes with their vertex attributes (normals, texture coordinates),
/// for receiver kinds that live on the surface of a mesh (lightmaps).
///
/// The blocker stream (ObjReader.h, GltfReader.h) only ever needs positions and never holds a
/// mesh; receivers on a mesh need its connectivity and attributes, so the meshes named as
/// receivers are loaded whole, here.
///
/// UV convention: texture coordinates follow glTF, (0, 0) at the top-left of the image and v
/// growing downwards. OBJ `vt` has v growing upwards, so OBJ coordinates are stored as
/// (u, 1 - v); an OBJ and a glTF exported from the same model then give the same layout.

#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace penumbra {

enum class GeometryFormat;  // stream/GeometryFile.h

/// @brief One mesh: per-vertex attributes (an attribute array is either empty, meaning the mesh
/// does not have it, or holds one entry per position) and a triangle list.
struct IndexedMesh {
    std::vector<glm::vec3> position;  ///< world space (the load transform applied)
    std::vector<glm::vec3> normal;    ///< shading normals, unit length, world space; may be empty
    std::vector<glm::vec2> uv0;       ///< OBJ vt or glTF TEXCOORD_0; may be empty
    std::vector<glm::vec2> uv1;       ///< glTF TEXCOORD_1; may be empty
    std::vector<uint32_t> indices;    ///< three per triangle, counter-clockwise front faces
    std::string name;                 ///< glTF mesh (or node) name; the file's stem for OBJ

    size_t triangleCount() const { return indices.size() / 3; }
};

/// @brief @p n scaled to unit length in float, or 0 when it has none (a normal as read).
glm::vec3 unitOrZero(const glm::vec3& n);

/// @brief Where a mesh is placed: positions by a matrix (in double), normals by its inverse
/// transpose, so that non-uniform scales keep them perpendicular to the surface, and the winding
/// reversed when the matrix mirrors, so that front faces stay front faces.
struct MeshPlacement {
    explicit MeshPlacement(const glm::dmat4& matrix);
    glm::dmat4 matrix;
    glm::dmat3 normalMatrix;
    bool mirrors;
    glm::vec3 position(const glm::vec3& p) const;
    /// Unit length, or 0 for a normal the matrix sends to 0 or past the float range.
    glm::vec3 normal(const glm::vec3& n) const;
};

/// @brief Loads every mesh of an OBJ (one per o/g group), .gltf or .glb file (one mesh per node
/// that draws one, all its triangle primitives merged).
///
/// OBJ: statements are read by ObjTokenizer.h, exactly as the blocker stream reads them (same
/// numbers to the bit, same errors); `v`, `vt`, `vn` and `f` with any corner form; polygons are
/// triangulated as the blocker stream does (triangulatePolygon()); corners with distinct (v, vt, vn) triples become distinct vertices. Every
/// `o` or `g` group with faces is a mesh named after the group (a file without groups, or with
/// one, gives one mesh named after the file's stem). A mesh has uv0 (normals) only when every
/// face corner names a `vt` (`vn`). Positions are transformed with the blocker stream's float
/// arithmetic (transformPoint), so they match its triangles bit for bit. glTF: POSITION, NORMAL, TEXCOORD_0, TEXCOORD_1 and
/// indices of TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN primitives, with node transforms; an
/// attribute is kept only when every primitive of the mesh has it. Mirroring transforms reverse
/// the winding so front faces stay front faces.
/// @param path the file
/// @param transform applied to positions (as points) and normals (inverse transpose)
/// @param parts OBJ only: the o/g groups to load (empty: all); a name the file lacks is an error
/// @param format the reader: OBJ, else glTF by content; a scene entry's type chooses it (an OBJ
///        may be called mesh.txt). nullopt: by extension, .obj or glTF.
/// @throw InputError naming the file for malformed input: bad numbers or indices
///        (`mesh.obj:12: face index 40 out of range (38 vertices)`), out-of-bounds or mistyped
///        accessors, attribute counts that differ from POSITION, non-finite values.
std::vector<IndexedMesh> loadIndexedMeshes(const std::string& path, const glm::mat4& transform,
                                           const std::vector<std::string>& parts = {},
                                           std::optional<GeometryFormat> format = std::nullopt);

}  // namespace penumbra
