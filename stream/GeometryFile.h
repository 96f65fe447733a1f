#pragma once
/// @file GeometryFile.h
/// @brief Geometry files by name: opening any supported format, summarising a source, and
/// converting between formats.

#include "stream/GltfAlpha.h"
#include "stream/TriangleSource.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace penumbra {

/// The geometry file formats (.gltf and .glb are one format: the reader tells them apart by content).
enum class GeometryFormat { Obj, Gltf, Ptri };

/// @brief The format a file name's extension names (case-insensitive), if any.
std::optional<GeometryFormat> geometryFormatOf(const std::string& path);

/// @brief Opens a geometry file, choosing the reader by extension (case-insensitive):
/// .obj (ObjReader.h), .gltf / .glb (GltfReader.h), .ptri (PtriFormat.h).
/// @param parts OBJ o/g groups to read (empty: all); an error for other formats.
/// @throw InputError naming @p path for an unknown extension, or whatever the reader throws.
TriangleSourcePtr openGeometryFile(const std::string& path, const std::vector<std::string>& parts = {});

/// @brief Opens a geometry file with the reader of @p format, whatever its name. Only regular
/// files are opened (InputFile.h: a FIFO or device is refused before any reader sees it), and an
/// OBJ must be text (ObjText.h); a non-empty OBJ without faces gets a warning.
/// @param parts as above.
/// @param gltfAlpha a glTF file's alpha ids (GltfAlpha.h); ignored for other formats.
/// @throw InputError naming @p path, or whatever the reader throws.
TriangleSourcePtr openGeometryFile(const std::string& path, GeometryFormat format, const std::vector<std::string>& parts = {},
                                   std::shared_ptr<const GltfAlphaIds> gltfAlpha = nullptr);

/// What a pass over a source found.
struct GeometryInfo {
    uint64_t triangles = 0;
    glm::vec3 lo{0}, hi{0};  ///< bounds of all vertices; both zero when there are no triangles
    double area = 0;         ///< total surface area, accumulated in double precision
};

/// @brief Reads @p source from the start to the end and summarises it.
/// The source is rewound before and after, so it can be handed on for the real pass.
/// @throw InputError when the source does.
GeometryInfo scanGeometry(TriangleSource& source);

/// @brief Writes every triangle of @p in (from its start) to @p outPath.
///
/// The format follows the extension: .ptri (PtriWriter, chunked and checksummed), .obj
/// (streamed; three `v` lines and one `f` line per triangle, vertices not shared), or
/// .glb / .gltf (one non-indexed FLOAT mesh with an identity node, the layout `generate` promises,
/// in primitives of at most GltfStreamWriter::kOpenBytes, written through a scratch file because
/// the JSON must state the buffer size first; .gltf embeds the buffer as a base64 data URI up to
/// kMaxDataUriBytes, else writes it to STEM.bin beside it). Floats are written so that they read back bit-identical. Triangle flags
/// survive only in .ptri.
/// Output is atomic: a temporary in the same directory is renamed into place at the end.
/// @throw InputError naming @p outPath for an unknown extension or a failed write, or when the
///        source throws; no partial output is left behind.
void convertGeometry(TriangleSource& in, const std::string& outPath);

/// @brief Refuses an output path whose extension names no format convertGeometry() writes, so a
/// command can say so before its work and its warnings.
/// @throw InputError "PATH: unknown output extension '.stl' (expected .obj, .gltf, .glb or .ptri)"
void checkGeometryOutputExtension(const std::string& outPath);

/// @brief `penumbra convert`: the file @p inPath written as @p outPath. An OBJ or glTF written as
/// glTF keeps its meshes (one per OBJ o/g group or glTF node), their normals and texture
/// coordinates (in glTF's convention), with identical corners welded; a .ptri
/// written as glTF is one indexed mesh whose corners with bit-identical positions are shared
/// (GltfConvert.h, GltfStreamWriter.h: in bounded memory, a mesh larger than the writer's open
/// bytes split into primitives); every other pair goes through convertGeometry().
/// @param progressQuiet set: each pass over the input shows as a phase on stderr (`[check
/// mesh.obj]` and `[load mesh.obj]` for a large OBJ, `[convert mesh.obj]` for the streamed
/// pass), printed or quiet as given; unset (library callers, tests): no display.
/// @throw InputError naming the file that is malformed or cannot be written.
void convertGeometryFile(const std::string& inPath, const std::string& outPath, std::optional<bool> progressQuiet = std::nullopt);

}  // namespace penumbra
