#include "stream/GltfJson.h"

#include <cctype>

namespace penumbra {

const GltfJson& gltfArrayOf(const std::string& path, const GltfJson& root, const char* key) {
    static const GltfJson empty = GltfJson::array();
    auto it = root.find(key);
    if (it == root.end()) return empty;
    if (!it->is_array()) fail(path, "\"{}\" must be an array", key);
    for (const GltfJson& e : *it)
        if (!e.is_object()) fail(path, "\"{}\" must be an array of objects", key);
    return *it;
}

std::string gltfPercentDecoded(const std::string& uri) {
    std::string out;
    for (size_t i = 0; i < uri.size(); ++i) {
        if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(uint8_t(uri[i + 1])) && std::isxdigit(uint8_t(uri[i + 2]))) {
            out.push_back(char(std::stoi(uri.substr(i + 1, 2), nullptr, 16)));
            i += 2;
        } else {
            out.push_back(uri[i]);
        }
    }
    return out;
}

bool decodeGltfBase64(std::string_view text, std::vector<uint8_t>& out) {
    auto value = [](char c) -> int {
        if (c >= 'A' && c <= 'Z') return c - 'A';
        if (c >= 'a' && c <= 'z') return c - 'a' + 26;
        if (c >= '0' && c <= '9') return c - '0' + 52;
        if (c == '+' || c == '-') return 62;
        if (c == '/' || c == '_') return 63;
        return -1;
    };
    uint32_t acc = 0;
    int bits = 0;
    for (char c : text) {
        if (c == '=') break;
        const int v = value(c);
        if (v < 0) return false;
        acc = (acc << 6) | uint32_t(v), bits += 6;
        if (bits >= 8) bits -= 8, out.push_back(uint8_t(acc >> bits));
    }
    return true;
}

}  // namespace penumbra
