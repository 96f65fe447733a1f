#include "stream/GltfAlpha.h"

#include "stream/AlphaImage.h"

#include "stream/GltfBytes.h"
#include "stream/GltfJson.h"
#include "stream/GltfPrimitive.h"
#include "stream/Translucency.h"
#include "stream/Triangle.h"
#include "stream/util/Error.h"
#include "stream/util/InputFile.h"
#include "stream/util/RegularFile.h"
#include "stream/util/SafePath.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <tuple>

namespace penumbra {
namespace {

/// Bytes of one deduplication index node (key, id, tree links), for the plan.
constexpr uint64_t kIndexNodeBytes = 112;

using Material = GltfMaterialDesc;

bool isMask(const Material& m) { return m.alphaMode == Material::AlphaMode::Mask; }

/// Every triangle primitive whose material is MASK, in file order.
std::vector<GltfPrimitiveLayout> maskPrimitives(const GltfDocument& doc) {
    std::vector<GltfPrimitiveLayout> out;
    for (size_t m = 0; m < doc.meshes.size(); ++m)
        for (size_t p = 0; p < doc.meshes[m].primitives.size(); ++p) {
            const int material = doc.meshes[m].primitives[p].material;
            if (material < 0 || !isMask(doc.materials.materials[size_t(material)])) continue;
            if (auto layout = gltfTrianglePrimitive(doc, int(m), int(p))) out.push_back(*layout);
        }
    return out;
}

/// "FILE: material M ("name"): image I (uri)".
std::string imageWhere(const GltfDocument& doc, int material, int image) {
    const GltfImageDesc& desc = doc.materials.images[size_t(image)];
    std::string where = fmt::format("{}: image {}", doc.materials.where(doc.path, material), image);
    if (!desc.uri.empty() && desc.uri.rfind("data:", 0) != 0) where += fmt::format(" (\"{}\")", desc.uri);
    return where;
}

/// The image a MASK material's texture shows. @throw InputError for a texture without a PNG or JPEG image.
int textureImage(const GltfDocument& doc, int material) {
    const Material& m = doc.materials.materials[size_t(material)];
    const GltfTextureDesc& t = doc.materials.textures[size_t(m.baseTexture)];
    if (t.source >= 0) return t.source;
    const std::string where = fmt::format("{}: texture {}", doc.materials.where(doc.path, material), m.baseTexture);
    if (!t.extensionImage.empty()) fail(where, "has only a {} image, which penumbra does not decode (give a PNG or JPEG source)", t.extensionImage);
    fail(where, "has no image source");
}

/// The encoded bytes of @p image. @throw InputError naming @p where.
std::vector<uint8_t> encodedBytes(const GltfDocument& doc, GltfBytes& bytes, int image, const std::string& where) {
    const GltfImageDesc& desc = doc.materials.images[size_t(image)];
    std::vector<uint8_t> out;
    if (desc.bufferView >= 0) {
        const GltfBufferView& view = doc.views[size_t(desc.bufferView)];
        if (view.meshopt) fail(where, "bufferView {} is EXT_meshopt_compression data, not an image", desc.bufferView);
        if (view.byteLength > kMaxEncodedImageBytes) fail(where, "bufferView {} holds {} bytes, more than an image may", desc.bufferView, view.byteLength);
        out.resize(size_t(view.byteLength));
        bytes.copy(view.buffer, view.byteOffset, view.byteLength, out.data());
        return out;
    }
    if (desc.uri.rfind("data:", 0) == 0) {
        const size_t comma = desc.uri.find(',');
        if (comma == std::string::npos || desc.uri.substr(0, comma).find(";base64") == std::string::npos)
            fail(where, "only base64 data URIs are supported");
        if (!decodeGltfBase64(std::string_view(desc.uri).substr(comma + 1), out)) fail(where, "malformed base64 in its data: URI");
        return out;
    }
    if (desc.uri.find("://") != std::string::npos) fail(where, "URI \"{}\" is not a local file", desc.uri);
    const std::filesystem::path base = std::filesystem::path(doc.path).parent_path();
    const std::string file = containedPath(base, gltfPercentDecoded(desc.uri), where, "the model's directory");
    return readAlphaImageFile(file, where);
}

AlphaWrap wrapOf(int mode) {
    return mode == kGltfClampToEdge ? AlphaWrap::Clamp : mode == kGltfMirroredRepeat ? AlphaWrap::Mirror : AlphaWrap::Repeat;
}

/// KHR_texture_transform's uv' = T R S uv with R = [cos sin; -sin cos], as the extension writes it.
std::array<double, 6> transformOf(const std::optional<GltfTextureTransform>& t) {
    if (!t) return {1, 0, 0, 0, 1, 0};
    const double c = std::cos(t->rotation), s = std::sin(t->rotation);
    return {c * t->scale[0], s * t->scale[1], t->offset[0], -s * t->scale[0], c * t->scale[1], t->offset[1]};
}

/// Builds one file's maps and ids.
class AlphaBuilder {
public:
    AlphaBuilder(const GltfDocument& doc, AlphaTable& table, double maxDistance)
        : doc_(doc), table_(table), maxDistance_(maxDistance), bytes_(doc, 0) {}

    std::shared_ptr<GltfAlphaIds> build() {
        auto ids = std::make_shared<GltfAlphaIds>();
        for (const GltfPrimitiveLayout& layout : maskPrimitives(doc_))
            ids->primitives.emplace(std::pair{layout.mesh, layout.primitive}, primitive(layout));
        return ids;
    }

private:
    /// The map of material @p material: its index, or opaque / kGltfAlphaNoCast for a constant one.
    uint32_t materialMap(int material, bool& constant) {
        const Material& m = doc_.materials.materials[size_t(material)];
        constant = true;
        if (m.baseTexture < 0) return m.baseAlpha >= m.alphaCutoff ? 0u : kGltfAlphaNoCast;
        const int image = textureImage(doc_, material);
        const GltfTextureDesc& texture = doc_.materials.textures[size_t(m.baseTexture)];
        const GltfSamplerDesc sampler = texture.sampler >= 0 ? doc_.materials.samplers[size_t(texture.sampler)] : GltfSamplerDesc{};
        const std::array<double, 6> transform = transformOf(m.transform);
        const auto key = std::tuple{image, m.alphaCutoff, m.baseAlpha, sampler.wrapS, sampler.wrapT, transform};
        if (auto it = maps_.find(key); it != maps_.end()) return constant = it->second.second, it->second.first;
        const auto decodedKey = std::tuple{image, m.alphaCutoff, m.baseAlpha};
        auto d = decoded_.find(decodedKey);
        if (d == decoded_.end()) {
            const std::string where = imageWhere(doc_, material, image);
            const std::vector<uint8_t> data = encodedBytes(doc_, bytes_, image, where);
            const AlphaImageHeader header = readAlphaImageHeader(data, doc_.materials.images[size_t(image)].mimeType, where);
            d = decoded_.emplace(decodedKey, decodeAlphaImage(data, header, m.baseAlpha, m.alphaCutoff, where)).first;
        }
        const AlphaMap& bits = d->second;
        const size_t texels = size_t(bits.width) * bits.height;
        size_t set = 0;
        for (size_t k = 0; k < texels; ++k) set += bits.at(uint32_t(k % bits.width), uint32_t(k / bits.width));
        uint32_t index = set == texels ? 0u : set == 0 ? kGltfAlphaNoCast : ~1u;
        constant = index != ~1u;
        if (!constant) {
            AlphaMap map = bits;
            map.wrapS = wrapOf(sampler.wrapS), map.wrapT = wrapOf(sampler.wrapT);
            map.transform = transform;
            map.name = doc_.materials.where(doc_.path, material);
            index = table_.addMap(std::move(map));
        }
        maps_.emplace(key, std::pair{index, constant});
        return index;
    }

    GltfPrimitiveAlpha primitive(const GltfPrimitiveLayout& layout) {
        const int material = doc_.meshes[size_t(layout.mesh)].primitives[size_t(layout.primitive)].material;
        const Material& m = doc_.materials.materials[size_t(material)];
        GltfPrimitiveAlpha out;
        bool constant = true;
        const uint32_t map = materialMap(material, constant);
        if (constant) return out.constant = map, out;
        const int set = m.transform && m.transform->texCoord >= 0 ? m.transform->texCoord : m.texCoord;
        const std::string name = fmt::format("TEXCOORD_{}", set);
        GltfPrimitiveReader reader(doc_, bytes_, layout, true);
        if (!reader.has(name))
            fail(doc_.materials.where(doc_.path, material), "uses texCoord {}, but {} has no {}", set, layout.where(doc_), name);
        out.ids.resize(size_t(layout.triangles));
        for (uint64_t t = 0; t < layout.triangles; ++t) {
            const std::array<uint32_t, 3> v = reader.triangle(t);
            AlphaEntry e;
            e.map = map, e.maxDistance = maxDistance_;
            for (int c = 0; c < 3; ++c) e.uv[size_t(c)] = glm::dvec2(glm::vec2(reader.attribute(name, 2, v[size_t(c)])));
            out.ids[size_t(t)] = entry(e);
        }
        return out;
    }

    uint32_t entry(const AlphaEntry& e) {
        const auto key = std::tuple{e.map, e.uv[0].x, e.uv[0].y, e.uv[1].x, e.uv[1].y, e.uv[2].x, e.uv[2].y, e.maxDistance};
        if (auto it = entries_.find(key); it != entries_.end()) return it->second;
        if (table_.entries() >= kTranslucentIdBase)  // higher ids are translucent surfaces' (Translucency.h)
            fail(doc_.path, "more than {} alpha-tested triangles with distinct texture coordinates (the alpha id space of a bake)",
                 kTranslucentIdBase - 1);
        const uint32_t id = table_.addEntry(e);
        entries_.emplace(key, id);
        return id;
    }

    const GltfDocument& doc_;
    AlphaTable& table_;
    double maxDistance_;
    GltfBytes bytes_;
    std::map<std::tuple<int, double, double>, AlphaMap> decoded_;
    std::map<std::tuple<int, double, double, int, int, std::array<double, 6>>, std::pair<uint32_t, bool>> maps_;
    std::map<std::tuple<uint32_t, double, double, double, double, double, double, double>, uint32_t> entries_;
};

}  // namespace

uint64_t GltfAlphaIds::bytes() const {
    uint64_t total = sizeof(*this);
    for (const auto& [key, p] : primitives) total += kIndexNodeBytes + p.ids.capacity() * sizeof(uint32_t);
    return total;
}

GltfAlphaPlan planGltfAlpha(const GltfDocument& doc) {
    GltfAlphaPlan plan;
    GltfBytes bytes(doc, 0);
    std::map<int, size_t> seen;  // image -> plan.images
    for (const GltfPrimitiveLayout& layout : maskPrimitives(doc)) {
        const int material = doc.meshes[size_t(layout.mesh)].primitives[size_t(layout.primitive)].material;
        const Material& m = doc.materials.materials[size_t(material)];
        ++plan.maskPrimitives;
        if (m.baseTexture < 0) continue;
        plan.alphaTriangles += layout.triangles;
        const int image = textureImage(doc, material);
        if (seen.count(image)) continue;
        GltfAlphaImage info;
        info.where = imageWhere(doc, material, image);
        const AlphaImageHeader h = readAlphaImageHeader(encodedBytes(doc, bytes, image, info.where), doc.materials.images[size_t(image)].mimeType, info.where);
        info.width = uint32_t(h.width), info.height = uint32_t(h.height);
        info.decodeBytes = h.decodeBytes();
        info.bitBytes = h.bitBytes();
        seen.emplace(image, plan.images.size());
        plan.images.push_back(info);
    }
    uint64_t largest = 0, bits = 0;
    for (const GltfAlphaImage& i : plan.images) largest = std::max(largest, i.decodeBytes + i.bitBytes), bits += i.bitBytes + sizeof(AlphaMap);
    plan.tableBytes = bits + plan.alphaTriangles * (sizeof(AlphaEntry) + sizeof(uint32_t));
    plan.buildBytes = largest + plan.alphaTriangles * kIndexNodeBytes + kGltfCacheBlocks * kGltfBlockBytes;
    return plan;
}

std::shared_ptr<const GltfAlphaIds> buildGltfAlpha(const GltfDocument& doc, AlphaTable& table, double maxDistance) {
    return AlphaBuilder(doc, table, maxDistance).build();
}

}  // namespace penumbra
