#pragma once
/// @file GltfMaterials.h
/// @brief The part of a glTF document's materials that decides what blocks light: alphaMode,
/// alphaCutoff, the base colour's alpha factor and texture (with its texCoord and
/// KHR_texture_transform), and the textures, images and samplers behind it. Parsed and checked
/// with the rest of the document (GltfDocument.h); images are not read here (GltfAlpha.h).

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace penumbra {

// glTF sampler wrap modes, as in the specification.
inline constexpr int kGltfClampToEdge = 33071, kGltfMirroredRepeat = 33648, kGltfRepeat = 10497;

/// KHR_texture_transform on a textureInfo.
struct GltfTextureTransform {
    std::array<double, 2> offset{0, 0}, scale{1, 1};
    double rotation = 0;  ///< radians, counter-clockwise in UV space as the extension defines
    int texCoord = -1;    ///< overrides the textureInfo's texCoord when >= 0
};

struct GltfMaterialDesc {
    enum class AlphaMode { Opaque, Mask, Blend };
    std::string name;
    AlphaMode alphaMode = AlphaMode::Opaque;
    double alphaCutoff = 0.5;
    double baseAlpha = 1.0;   ///< baseColorFactor[3]
    int baseTexture = -1;     ///< pbrMetallicRoughness.baseColorTexture.index, or -1
    int texCoord = 0;         ///< its texCoord (TEXCOORD_n)
    std::optional<GltfTextureTransform> transform;
};

struct GltfTextureDesc {
    int source = -1;   ///< image, or -1 when only an extension (KHR_texture_basisu, EXT_texture_webp) names one
    int sampler = -1;  ///< -1: repeat in both directions
    std::string extensionImage;  ///< the extension that names the only image, for the message
};

struct GltfImageDesc {
    std::string uri;       ///< a relative file name or a data: URI; empty with a bufferView
    int bufferView = -1;
    std::string mimeType;
};

struct GltfSamplerDesc {
    int wrapS = kGltfRepeat, wrapT = kGltfRepeat;
};

/// @brief Everything above, as one document holds it.
struct GltfMaterialTables {
    std::vector<GltfMaterialDesc> materials;
    std::vector<GltfTextureDesc> textures;
    std::vector<GltfImageDesc> images;
    std::vector<GltfSamplerDesc> samplers;

    /// "FILE: material M ("name")", the prefix of every message about material @p m.
    std::string where(const std::string& path, int m) const;
};

/// @brief Parses "materials", "textures", "images" and "samplers" of the glTF JSON @p root.
/// @param views the document's buffer view count, for the images' references.
/// @throw InputError naming @p path and the object for wrong types, out-of-range references,
///        unknown alpha modes and wrap modes, and non-finite factors or transforms.
GltfMaterialTables parseGltfMaterials(const std::string& path, const nlohmann::json& root, size_t views);

}  // namespace penumbra
