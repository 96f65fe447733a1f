#pragma once
/// @file GltfReader.h
/// @brief Streaming reader for glTF 2.0 scenes (.gltf with external or embedded buffers, and
/// .glb), in bounded memory.
///
/// Memory contract: only the JSON document stays resident (GltfDocument.h: compact tables, no
/// buffer bytes), plus, whatever the file size or instance count: the byte window cache of
/// GltfBytes.h (32 blocks of 64 KiB = 2 MiB), one block of 1024 triangles in local coordinates
/// (40 KiB), and for compressed files the largest primitive's decode working set (a decoded
/// EXT_meshopt_compression view pair, or one decoded KHR_draco_mesh_compression primitive).
/// residentBytes() reports that sum as soon as the file is open. Buffers are read with pread(2),
/// never mapped, so a bake works under an address-space cap smaller than the file.
///
/// Geometry: the default scene (else scene 0, else every root node when the file has no scenes)
/// is walked parent to child, composing node matrices and TRS (T * R * S) in double precision.
/// Primitives of mode TRIANGLES, TRIANGLE_STRIP (alternating winding) and TRIANGLE_FAN are read,
/// indexed (UNSIGNED_BYTE/SHORT/INT) or not, through the one walker of GltfPrimitive.h; POSITION
/// may be FLOAT or, as KHR_mesh_quantization allows, BYTE/UNSIGNED_BYTE/SHORT/UNSIGNED_SHORT,
/// normalized or not. Point and line primitives are skipped with one warning line per mode on
/// stderr. Nodes with a mirroring transform get the winding of their triangles reversed (glTF
/// front faces follow the determinant), and identity transforms leave coordinates bit-exact.
///
/// Instancing without copies: every node that draws a mesh, and every instance of a node's
/// EXT_mesh_gpu_instancing (TRANSLATION, ROTATION, SCALE; instance T * R * S, then the node's
/// world matrix), places the same primitive. A primitive's triangles are decoded block by block
/// (1024 at a time) and each block is emitted once per placement and instance, so the mesh is
/// read once per pass and memory does not depend on the instance count. Alpha-tested triangles
/// keep their corner order under mirroring transforms (their UVs follow the corners).

#include "stream/GltfAlpha.h"
#include "stream/TriangleSource.h"

#include <memory>
#include <string>

namespace penumbra {

/// @brief Opens a .gltf or .glb file (told apart by content) as a triangle source.
/// @param path the file; messages name it as given.
/// @param alpha the file's alpha ids (GltfAlpha.h, buildGltfAlpha()): a MASK primitive's triangles
///        get their alpha id (or kTriangleNoCast when fully transparent). Null: every triangle is
///        opaque, as for an export.
/// @return a source whose sizeHint() is the exact triangle count of the scene.
/// @throw InputError naming the file and the offending object, e.g. `box.gltf: accessor 3 reads
///        past the end of bufferView 1 (needs 480 bytes, has 240)`. read() throws for indices
///        out of range, non-finite positions and compressed data that does not decode.
TriangleSourcePtr openGltf(const std::string& path, std::shared_ptr<const GltfAlphaIds> alpha = nullptr);

/// @brief What opening a glTF holds: @ref parse while its JSON is parsed (text and tree, about 13
/// bytes per byte of JSON, freed after), and @ref held that the opened document keeps per JSON
/// object (nodes, their placements).
struct GltfOpeningBytes {
    uint64_t parse = 0, held = 0;
    uint64_t total() const { return parse + held; }
};

/// @brief What opening @p path will hold, from the GLB header or the file's size and, when the
/// parse is notable, one pass over the JSON text that counts its objects: a memory check before
/// the opening, so that a refusal does not itself peak above the budget it refuses, and names
/// enough. Zero when the file cannot be read or its header is not a GLB's (opening says why).
GltfOpeningBytes gltfOpeningBytes(const std::string& path);

}  // namespace penumbra
