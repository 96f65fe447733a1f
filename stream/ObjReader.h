#pragma once
/// @file ObjReader.h
/// @brief Streaming reader for Wavefront OBJ meshes.
///
/// Memory contract: only the vertex array (`v` lines, 12 bytes per vertex) stays resident.
/// Opening the file makes one pass that stores the vertices and validates every face (so all
/// errors surface at open and sizeHint() is exact); faces are never stored. Each read()
/// continues a second, streaming pass over the file that starts at the remembered offset of
/// the first `f` line; rewind() seeks back to that offset. The file is read line by line and
/// never loaded whole, so a multi-gigabyte OBJ costs its vertex array plus one line buffer.
/// The file is closed between passes (reopened by the first read() after open or rewind()),
/// so a scene of many sources does not hold a descriptor per file.
///
/// Supported: `v x y z [w | r g b]` (only x y z are used), `f` with `v`, `v/vt`, `v//vn` and
/// `v/vt/vn` corners, positive and negative (relative) indices, polygons of any size
/// (fan-triangulated: (c0, c1, c2), (c0, c2, c3), ...), `#` comments, CRLF line ends.
/// Ignored: vt, vn, vp, o, g, s, usemtl, mtllib, l, p and any other statement. Line
/// continuation with a trailing backslash is not supported.
///
/// An index refers to the vertices defined *above* the face, as the OBJ format requires; a
/// face that names a vertex defined later is out of range.

#include "stream/TriangleSource.h"

#include <string>

namespace penumbra {

/// @brief Opens an OBJ file as a streaming triangle source.
/// @param path the .obj file; messages name it as given.
/// @return a source whose sizeHint() is the exact triangle count.
/// @throw InputError "PATH:LINE: problem" for an unreadable file, an unparsable number, a
///        non-finite coordinate, an index of 0 or out of range, or a face with fewer than three
///        corners, e.g. `mesh.obj:12: face index 40 out of range (38 vertices)`.
TriangleSourcePtr openObj(const std::string& path);

}  // namespace penumbra
