#include "stream/GltfMaterials.h"

#include "stream/GltfJson.h"

#include <cmath>

namespace penumbra {
namespace {

/// A finite number member, or @p fallback when absent.
double numberOr(const GltfMembers& m, const char* key, double fallback) {
    const GltfJson* v = m.find(key);
    if (!v) return fallback;
    if (!v->is_number() || !std::isfinite(v->get<double>())) fail(m.path, "{} {} must be a finite number", m.what, key);
    return v->get<double>();
}

GltfTextureTransform parseTransform(const GltfMembers& m) {
    GltfTextureTransform t;
    const std::vector<double> offset = m.numbers("offset"), scale = m.numbers("scale");
    for (const auto* values : {&offset, &scale}) {
        if (!values->empty() && values->size() != 2) fail(m.path, "{} offset and scale must hold 2 numbers", m.what);
        for (double x : *values)
            if (!std::isfinite(x)) fail(m.path, "{} offset and scale must be finite", m.what);
    }
    if (!offset.empty()) t.offset = {offset[0], offset[1]};
    if (!scale.empty()) t.scale = {scale[0], scale[1]};
    t.rotation = numberOr(m, "rotation", 0.0);
    if (m.find("texCoord")) t.texCoord = m.index("texCoord");
    return t;
}

GltfMaterialDesc parseMaterial(const std::string& path, const GltfJson& j, size_t i, size_t textures) {
    GltfMembers m{path, j, fmt::format("material {}", i)};
    GltfMaterialDesc mat;
    mat.name = m.string("name");
    if (!mat.name.empty()) m.what += fmt::format(" (\"{}\")", mat.name);
    const std::string mode = m.find("alphaMode") ? m.string("alphaMode") : "OPAQUE";
    if (mode == "MASK") mat.alphaMode = GltfMaterialDesc::AlphaMode::Mask;
    else if (mode == "BLEND") mat.alphaMode = GltfMaterialDesc::AlphaMode::Blend;
    else if (mode != "OPAQUE") fail(path, "{} alphaMode \"{}\" is not OPAQUE, MASK or BLEND", m.what, mode);
    mat.alphaCutoff = numberOr(m, "alphaCutoff", 0.5);
    GltfMembers pbr{path, m.objectAt("pbrMetallicRoughness"), m.what + " pbrMetallicRoughness"};
    const std::vector<double> factor = pbr.numbers("baseColorFactor");
    if (!factor.empty() && (factor.size() != 4 || !std::isfinite(factor[3])))
        fail(path, "{} baseColorFactor must hold 4 finite numbers", pbr.what);
    if (!factor.empty()) mat.baseAlpha = factor[3];
    if (pbr.find("baseColorTexture")) {
        GltfMembers info{path, pbr.objectAt("baseColorTexture"), pbr.what + " baseColorTexture"};
        mat.baseTexture = info.index("index");
        if (mat.baseTexture < 0 || size_t(mat.baseTexture) >= textures)
            fail(path, "{} refers to texture {} (file has {})", info.what, info.find("index") ? mat.baseTexture : -1, textures);
        mat.texCoord = info.index("texCoord", 0);
        const GltfJson& extensions = info.objectAt("extensions");
        if (auto it = extensions.find("KHR_texture_transform"); it != extensions.end()) {
            if (!it->is_object()) fail(path, "{} KHR_texture_transform must be an object", info.what);
            mat.transform = parseTransform(GltfMembers{path, *it, info.what + " KHR_texture_transform"});
        }
    }
    return mat;
}

GltfTextureDesc parseTexture(const std::string& path, const GltfJson& j, size_t i, size_t images, size_t samplers) {
    GltfMembers m{path, j, fmt::format("texture {}", i)};
    GltfTextureDesc t;
    t.source = m.index("source");
    t.sampler = m.index("sampler");
    const GltfJson& extensions = m.objectAt("extensions");
    for (const char* name : {"KHR_texture_basisu", "EXT_texture_webp", "MSFT_texture_dds"})
        if (extensions.contains(name)) t.extensionImage = name;
    if (t.source >= int(images)) fail(path, "{} refers to image {} (file has {})", m.what, t.source, images);
    if (t.sampler >= int(samplers)) fail(path, "{} refers to sampler {} (file has {})", m.what, t.sampler, samplers);
    return t;
}

GltfImageDesc parseImage(const std::string& path, const GltfJson& j, size_t i, size_t views) {
    GltfMembers m{path, j, fmt::format("image {}", i)};
    GltfImageDesc image;
    image.uri = m.string("uri");
    image.bufferView = m.index("bufferView");
    image.mimeType = m.string("mimeType");
    if (image.bufferView >= int(views)) fail(path, "{} refers to bufferView {} (file has {})", m.what, image.bufferView, views);
    if (image.uri.empty() == (image.bufferView < 0)) fail(path, "{} must have either a uri or a bufferView", m.what);
    return image;
}

GltfSamplerDesc parseSampler(const std::string& path, const GltfJson& j, size_t i) {
    GltfMembers m{path, j, fmt::format("sampler {}", i)};
    GltfSamplerDesc s;
    for (auto [key, wrap] : {std::pair{"wrapS", &s.wrapS}, std::pair{"wrapT", &s.wrapT}}) {
        *wrap = int(m.unsignedOr(key, kGltfRepeat));
        if (*wrap != kGltfRepeat && *wrap != kGltfClampToEdge && *wrap != kGltfMirroredRepeat)
            fail(path, "{} {} {} is not 33071, 33648 or 10497", m.what, key, *wrap);
    }
    return s;
}

}  // namespace

std::string GltfMaterialTables::where(const std::string& path, int m) const {
    const std::string& name = materials[size_t(m)].name;
    return name.empty() ? fmt::format("{}: material {}", path, m) : fmt::format("{}: material {} (\"{}\")", path, m, name);
}

GltfMaterialTables parseGltfMaterials(const std::string& path, const nlohmann::json& root, size_t views) {
    GltfMaterialTables t;
    const GltfJson &images = gltfArrayOf(path, root, "images"), &samplers = gltfArrayOf(path, root, "samplers"),
                   &textures = gltfArrayOf(path, root, "textures"), &materials = gltfArrayOf(path, root, "materials");
    for (size_t i = 0; i < images.size(); ++i) t.images.push_back(parseImage(path, images[i], i, views));
    for (size_t i = 0; i < samplers.size(); ++i) t.samplers.push_back(parseSampler(path, samplers[i], i));
    for (size_t i = 0; i < textures.size(); ++i)
        t.textures.push_back(parseTexture(path, textures[i], i, images.size(), samplers.size()));
    for (size_t i = 0; i < materials.size(); ++i) t.materials.push_back(parseMaterial(path, materials[i], i, textures.size()));
    return t;
}

}  // namespace penumbra
