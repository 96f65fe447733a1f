#pragma once
/// @file GltfDraco.h
/// @brief KHR_draco_mesh_compression: one primitive decoded whole with Debian's libdraco (Draco
/// has no partial decoding), into plain arrays that GltfPrimitiveReader reads from. A reader
/// holds at most one decoded primitive; dracoDecodeBytes() (GltfPrimitive.h) is its size.

#include "stream/GltfBytes.h"
#include "stream/GltfPrimitive.h"

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include <string>
#include <utility>
#include <vector>

namespace penumbra {

struct DracoPrimitive {
    std::vector<glm::vec3> positions;  ///< per point, dequantized
    std::vector<uint32_t> indices;     ///< three per face
    std::vector<std::pair<std::string, std::vector<glm::vec4>>> attributes;  ///< other attributes, per point
};

/// @brief Decodes the Draco data of @p layout. @p allAttributes decodes every attribute the
/// extension lists, else POSITION only.
/// @throw InputError "FILE: mesh M primitive P: ..." when the data does not decode, lacks
///        POSITION, or disagrees with the primitive's accessors (counts).
DracoPrimitive decodeDracoPrimitive(const GltfDocument& doc, GltfBytes& bytes, const GltfPrimitiveLayout& layout,
                                    bool allAttributes);

}  // namespace penumbra
