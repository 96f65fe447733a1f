#include "stream/GlbBuilder.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"

#include <stb/stb_image_write.h>

#include <algorithm>
#include <cmath>
#include <cstring>

namespace penumbra {
namespace {

constexpr char kBase64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

}  // namespace

std::string encodeBase64(const std::vector<uint8_t>& in) {
    std::string out;
    for (size_t i = 0; i < in.size(); i += 3) {
        const uint32_t n = uint32_t(in[i]) << 16 | (i + 1 < in.size() ? uint32_t(in[i + 1]) << 8 : 0u) |
                           (i + 2 < in.size() ? uint32_t(in[i + 2]) : 0u);
        out += kBase64[(n >> 18) & 63];
        out += kBase64[(n >> 12) & 63];
        out += i + 1 < in.size() ? kBase64[(n >> 6) & 63] : '=';
        out += i + 2 < in.size() ? kBase64[n & 63] : '=';
    }
    return out;
}

namespace {

void put32(std::vector<uint8_t>& out, uint32_t v) {
    for (int i = 0; i < 4; ++i) out.push_back(uint8_t(v >> (8 * i)));
}

}  // namespace

GlbBuilder::GlbBuilder() {
    json = {{"asset", {{"version", "2.0"}, {"generator", "penumbra"}}}};
}

int GlbBuilder::append(const std::string& key, nlohmann::json value) {
    if (!json.contains(key)) json[key] = nlohmann::json::array();
    json[key].push_back(std::move(value));
    return int(json[key].size() - 1);
}

int GlbBuilder::addView(const void* data, size_t size) {
    while (bin_.size() % 4) bin_.push_back(0);
    const size_t offset = bin_.size();
    bin_.resize(offset + size);
    if (size) std::memcpy(bin_.data() + offset, data, size);
    return append("bufferViews", {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", size}});
}

int GlbBuilder::addAccessor(const void* data, size_t count, int componentType, const std::string& type, bool normalized) {
    const int components = type == "SCALAR" ? 1 : type == "VEC2" ? 2 : type == "VEC3" ? 3 : 4;
    const int bytes = componentType == 5126 || componentType == 5125 ? 4 : componentType == 5122 || componentType == 5123 ? 2 : 1;
    nlohmann::json a = {{"bufferView", addView(data, count * size_t(components * bytes))},
                        {"componentType", componentType}, {"count", count}, {"type", type}};
    if (normalized) a["normalized"] = true;
    if (componentType == 5126 && count > 0) {  // glTF requires POSITION's bounds; every float accessor gets them
        std::vector<float> lo(size_t(components), INFINITY), hi(size_t(components), -INFINITY);
        for (size_t i = 0; i < count * size_t(components); ++i) {
            float x;
            std::memcpy(&x, static_cast<const uint8_t*>(data) + 4 * i, 4);
            lo[i % size_t(components)] = std::min(lo[i % size_t(components)], x);
            hi[i % size_t(components)] = std::max(hi[i % size_t(components)], x);
        }
        a["min"] = lo, a["max"] = hi;
    }
    return append("accessors", std::move(a));
}

int GlbBuilder::addImage(const std::vector<uint8_t>& encoded, const std::string& mimeType) {
    return append("images", {{"bufferView", addView(encoded.data(), encoded.size())}, {"mimeType", mimeType}});
}

std::vector<uint8_t> GlbBuilder::bytes(bool binary) const {
    nlohmann::json doc = json;
    std::vector<uint8_t> bin = bin_;
    while (bin.size() % 4) bin.push_back(0);
    doc["buffers"] = nlohmann::json::array();
    if (binary) doc["buffers"].push_back({{"byteLength", bin.size()}});
    else doc["buffers"].push_back({{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + encodeBase64(bin)}});
    std::string text = doc.dump();
    if (!binary) return {text.begin(), text.end()};
    while (text.size() % 4) text += ' ';
    std::vector<uint8_t> out;
    put32(out, 0x46546C67u), put32(out, 2), put32(out, uint32_t(12 + 8 + text.size() + 8 + bin.size()));
    put32(out, uint32_t(text.size())), put32(out, 0x4E4F534Au);
    out.insert(out.end(), text.begin(), text.end());
    put32(out, uint32_t(bin.size())), put32(out, 0x004E4942u);
    out.insert(out.end(), bin.begin(), bin.end());
    return out;
}

void GlbBuilder::write(const std::string& path) const {
    const bool text = path.size() >= 5 && path.compare(path.size() - 5, 5, ".gltf") == 0;
    writeFileAtomically(path, bytes(!text));
}

std::vector<uint8_t> encodePngRgba(int width, int height, const std::vector<uint8_t>& rgba) {
    std::vector<uint8_t> out;
    auto sink = [](void* context, void* data, int size) {
        auto* o = static_cast<std::vector<uint8_t>*>(context);
        o->insert(o->end(), static_cast<uint8_t*>(data), static_cast<uint8_t*>(data) + size);
    };
    if (!stbi_write_png_to_func(sink, &out, width, height, 4, rgba.data(), width * 4))
        throw InputError("cannot encode a PNG image");
    return out;
}

}  // namespace penumbra
