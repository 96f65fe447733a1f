#pragma once
/// @file GltfReader.h
/// @brief Reader for glTF 2.0 scenes (.gltf with external or embedded buffers, and .glb).
///
/// The format keeps geometry in binary buffers addressed by JSON offsets, so the whole model
/// (JSON and buffers) is loaded by tinygltf and stays in memory; triangles are produced from
/// it in caller-sized chunks. Images are not decoded.
///
/// Geometry: the default scene (else scene 0, else every root node when the file has no
/// scenes) is walked parent to child, composing node matrices and TRS (T * R * S) in double
/// precision. Primitives of mode TRIANGLES, TRIANGLE_STRIP (alternating winding) and
/// TRIANGLE_FAN are read, indexed (UNSIGNED_BYTE/SHORT/INT) or not; POSITION may be FLOAT or,
/// as KHR_mesh_quantization allows, BYTE/UNSIGNED_BYTE/SHORT/UNSIGNED_SHORT, normalized or not.
/// Point and line primitives are skipped with one warning line per mode on stderr. Nodes with
/// a mirroring transform get the winding of their triangles reversed (glTF front faces follow
/// the determinant), and identity transforms leave coordinates bit-exact.
///
/// Trust: tinygltf parses the JSON but does not check that offsets stay inside buffers, so
/// every buffer view, accessor and index value is validated here before any byte is read,
/// and .glb chunk headers are checked before tinygltf sees them.

#include "stream/TriangleSource.h"

#include <string>

namespace penumbra {

/// @brief Opens a .gltf or .glb file (told apart by content) as a triangle source.
/// @param path the file; messages name it as given.
/// @return a source whose sizeHint() is the exact triangle count of the scene.
/// @throw InputError naming the file and the offending object, e.g. `box.gltf: accessor 3 reads
///        past the end of bufferView 1 (needs 480 bytes, has 240)`; tinygltf's own load errors
///        are reported as the file and tinygltf's first error line. read() throws for
///        non-finite positions.
TriangleSourcePtr openGltf(const std::string& path);

}  // namespace penumbra
