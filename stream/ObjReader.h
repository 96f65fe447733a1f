#pragma once
/// @file ObjReader.h
/// @brief Streaming reader for Wavefront OBJ meshes.
///
/// Memory contract: the vertex array (`v` lines, 12 bytes per vertex) is kept in a VertexStore
/// (VertexStore.h): the first million vertices in memory, the rest spilled to an anonymous
/// scratch file and read back through a 3 MiB block cache, so a reader holds at most about
/// 27 MiB (residentBytes(); less for files too small to hold a million vertices) whatever the
/// file size. Faces are never stored. The first read() (or
/// sizeHint()) makes one pass that stores the vertices and validates every statement (so all
/// errors surface before the first triangle and sizeHint() is exact); opening the reader only
/// checks that the file opens. Each read() continues a second, streaming pass over the file that
/// starts at the remembered offset of the first `f` line; rewind() seeks back to that offset. The
/// file is read line by line and never loaded whole. It is closed between passes (reopened by
/// the first read() after rewind()), so a scene of many sources does not hold a descriptor per
/// file.
///
/// Statements are read by ObjTokenizer.h, exactly as the receiver meshes (IndexedMesh.h) read
/// them, so one file gives blockers and receivers the same bits. Supported: `v x y z [w | r g b]`
/// (only x y z are used), `f` with `v`, `v/vt`, `v//vn` and `v/vt/vn` corners, positive and
/// negative (relative) indices, polygons of any size (triangulatePolygon(): convex ones as the
/// fan (c0, c1, c2), (c0, c2, c3), ..., concave ones by ear clipping), `#` comments (also after a statement), CRLF line ends, and `o`/`g` groups,
/// which a scene can pick with "parts". `vt` and `vn` are validated (they must be numbers, and
/// corners must refer to existing ones) but not kept. Ignored: vp, s, usemtl, mtllib, l, p and
/// any other statement. Line continuation with a trailing backslash is not supported.
///
/// An index refers to the vertices defined *above* the face, as the OBJ format requires; a
/// face that names a vertex defined later is out of range.

#include "stream/TriangleSource.h"

#include <string>
#include <vector>

namespace penumbra {

/// @brief Opens an OBJ file as a streaming triangle source.
/// @param path the .obj file; messages name it as given.
/// @param parts the o/g groups to stream (empty: every face); a name the file lacks is an error.
/// @return a source whose sizeHint() is the exact triangle count.
/// @throw InputError "PATH:LINE: problem" for an unreadable file, an unparsable number, a
///        non-finite coordinate, an index of 0 or out of range, or a face with fewer than three
///        corners, e.g. `mesh.obj:12: face index 40 out of range (38 vertices)`.
TriangleSourcePtr openObj(const std::string& path, const std::vector<std::string>& parts = {});

}  // namespace penumbra
