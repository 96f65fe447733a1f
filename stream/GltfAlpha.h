#pragma once
/// @file GltfAlpha.h
/// @brief glTF `alphaMode: "MASK"` materials as cut-out blockers (stream/AlphaTable.h).
///
/// A MASK primitive's texel is opaque when baseColorTexture alpha x baseColorFactor[3] >=
/// alphaCutoff (default 0.5), thresholded once when the texture is decoded into a 1-bit AlphaMap;
/// without a texture the whole primitive is opaque (factor >= cutoff) or casts nothing. Lookups
/// are nearest texel, no mipmaps: the sampler's min/mag filters are ignored, its wrapS/wrapT are
/// kept, and KHR_texture_transform (offset, rotation, scale, texCoord) becomes the map's affine
/// transform uv' = T R S uv exactly as the extension writes it. Images are PNG or JPEG (stb_image),
/// from a bufferView, a file next to the model (SafePath.h rules) or a data: URI; an image without
/// an alpha channel (every JPEG) has alpha 1. 16-bit PNGs are thresholded at 16 bits.
///
/// Work happens in two steps so that memory is checked before anything is decoded:
///  1. planGltfAlpha(): reads the images' headers only (stbi_info), and says what decoding needs
///     (the largest image's transient w x h x channels, twice for the decoder's own rows) and what
///     the table will hold (bits, and entries up to one per alpha triangle of the file).
///  2. buildGltfAlpha(): decodes each (image, cutoff, factor) once, makes one AlphaMap per
///     (image, cutoff, factor, sampler, transform), and gives every triangle of a MASK primitive
///     an alpha id for its corner UVs. Ids are deduplicated by (map, uv0, uv1, uv2, max distance)
///     in file order (mesh by mesh, primitive by primitive, triangle by triangle), so instances
///     share them, the count does not depend on how often a mesh is placed, and every pass of
///     every process (shards, resume) gives the same ids.

#include "stream/AlphaTable.h"
#include "stream/GltfDocument.h"

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace penumbra {

/// A triangle value of GltfPrimitiveAlpha: it casts nothing (a MASK material fully transparent).
inline constexpr uint32_t kGltfAlphaNoCast = ~0u;

/// @brief What one MASK primitive's triangles get: one value for all, or one per triangle.
struct GltfPrimitiveAlpha {
    uint32_t constant = 0;       ///< 0: opaque, kGltfAlphaNoCast, or an alpha id; used when ids is empty
    std::vector<uint32_t> ids;   ///< per triangle of the primitive, in the walker's order
    uint32_t at(uint64_t t) const { return ids.empty() ? constant : ids[size_t(t)]; }
};

/// @brief A file's MASK primitives, keyed by (mesh, primitive). Primitives not listed are opaque.
struct GltfAlphaIds {
    std::map<std::pair<int, int>, GltfPrimitiveAlpha> primitives;
    uint64_t bytes() const;
};

/// @brief One texture a MASK material reads, as its header describes it.
struct GltfAlphaImage {
    std::string where;       ///< "FILE: material M ("name"): image I", for messages
    uint32_t width = 0, height = 0;
    uint64_t decodeBytes = 0;  ///< transient bytes to decode it
    uint64_t bitBytes = 0;     ///< bytes of its 1-bit map
};

/// @brief What a file's alpha needs, before decoding.
struct GltfAlphaPlan {
    std::vector<GltfAlphaImage> images;
    uint64_t maskPrimitives = 0;  ///< primitives with a MASK material
    uint64_t alphaTriangles = 0;  ///< triangles of textured MASK primitives (each counted once)
    /// Bytes held once built: maps, entries (at most one per alpha triangle) and the per-triangle ids.
    uint64_t tableBytes = 0;
    /// The most held while building: the largest image's decode, and the deduplication index.
    uint64_t buildBytes = 0;
    bool empty() const { return maskPrimitives == 0; }
};

/// @brief Step 1: reads the headers of the images MASK materials use.
/// @throw InputError "FILE: material M ("name"): image I: ..." for a missing, unreadable,
///        corrupt, oversized or unsupported (not PNG or JPEG) image.
GltfAlphaPlan planGltfAlpha(const GltfDocument& doc);

/// @brief Step 2: decodes the textures into @p table and gives the MASK triangles their ids,
/// each limited to @p maxDistance (AlphaTable::withDistance; infinity: none).
/// @throw InputError as planGltfAlpha(), for a texture that does not decode, for texCoord sets
///        the primitive lacks, and when the table's 24-bit id space runs out (naming the file).
std::shared_ptr<const GltfAlphaIds> buildGltfAlpha(const GltfDocument& doc, AlphaTable& table, double maxDistance);

}  // namespace penumbra
