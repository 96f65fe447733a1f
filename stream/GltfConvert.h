#pragma once
/// @file GltfConvert.h
/// @brief The meshes of a file, or a triangle stream, into a GltfStreamWriter without holding
/// them: `penumbra convert` and `generate` to glTF in bounded memory.
///
/// Memory contract: an OBJ's `v`, `vt` and `vn` arrays go through VertexStore (15 MiB each at
/// most, the rest in a scratch file), a glTF's buffers through GltfBytes (2 MiB of blocks; a
/// meshopt-compressed view is decoded whole), and the writer holds its open primitives
/// (GltfStreamWriter::kOpenBytes). Nothing grows with the file but the writer's list of
/// primitives and the OBJ's group names.

#include "stream/GltfStreamWriter.h"
#include "stream/TriangleSource.h"

#include <string>

namespace penumbra {

struct GltfDocument;

/// @brief Every mesh of the OBJ or glTF at @p path, as loadIndexedMeshes() loads them: one mesh
/// per OBJ o/g group with faces (named after the group, or the file's stem when there is one),
/// or per glTF node that draws one (per instance of EXT_mesh_gpu_instancing), with the normals
/// and texture coordinates every corner of the mesh has. An OBJ is read twice: the first pass
/// checks it whole (so a malformed file writes nothing) and finds which attributes each group
/// keeps; the second emits the triangles.
/// @throw InputError naming the file and line (or accessor) for malformed input, and "file
///        changed while it was being read" when the passes disagree.
void addMeshesOfFile(const std::string& path, GltfStreamWriter& out);

/// @brief Warns once, naming @p path, when the glTF @p doc draws triangles whose materials cut out
/// or blend (alphaMode MASK or BLEND): @p command (`convert`, `generate`) writes geometry only,
/// so they lose them.
void warnIfMaterialsDropped(const std::string& path, const GltfDocument& doc, const char* command = "convert");

/// @brief The triangles of @p source, from its start, as one mesh named @p name.
void addTrianglesOf(TriangleSource& source, GltfStreamWriter& out, std::string name,
                    GltfStreamWriter::Indexing indexing);

}  // namespace penumbra
