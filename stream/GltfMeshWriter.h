#pragma once
/// @file GltfMeshWriter.h
/// @brief Indexed glTF output for `penumbra convert` and `generate`: welded vertices, the
/// normals and texture coordinates the input has, one glTF mesh and node per input mesh.

#include "stream/IndexedMesh.h"
#include "stream/TriangleSource.h"

#include <string>
#include <vector>

namespace penumbra {

/// @brief @p mesh with every set of vertices that agree bit for bit in position, normal and
/// texture coordinates merged into one (the first one's index order), and the triangles
/// renumbered. Triangles and their winding are unchanged.
IndexedMesh weldVertices(const IndexedMesh& mesh);

/// @brief Every triangle of @p source (from its start) as one mesh, corners with bit-identical
/// positions shared. Holds the whole mesh in memory: 12 bytes per distinct vertex and 12 per
/// triangle, plus a hash table of the vertices.
/// @throw InputError when the source does.
IndexedMesh meshOfTriangles(TriangleSource& source, std::string name);

/// @brief Writes @p meshes as one glTF (binary .glb when @p binary, else .gltf with the buffer
/// embedded as a data URI): per mesh a node and a mesh of one TRIANGLES primitive with POSITION
/// (with its min and max), NORMAL, TEXCOORD_0 and TEXCOORD_1 when the mesh has them, and
/// UNSIGNED_INT indices. Texture coordinates are IndexedMesh's, which follow glTF's top-left
/// origin already (an OBJ's v is flipped on load). Atomic: no partial file is left behind.
/// @throw InputError naming @p path when the model does not fit in a GLB (4 GiB) or a write fails.
void writeIndexedGltf(const std::vector<IndexedMesh>& meshes, const std::string& path, bool binary);

}  // namespace penumbra
