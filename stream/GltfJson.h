#pragma once
/// @file GltfJson.h
/// @brief Reading glTF JSON objects with one-line messages naming the file and the object
/// ("accessor 3 count must be ..."): shared by the document (GltfDocument.cpp) and its materials
/// (GltfMaterials.cpp). Internal to the glTF reader.

#include "stream/util/Error.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

namespace penumbra {

using GltfJson = nlohmann::json;

/// Reads typed members with messages naming the object ("accessor 3: count must be ...").
struct GltfMembers {
    const std::string& path;
    const GltfJson& object;
    std::string what;

    const GltfJson* find(const char* key) const {
        auto it = object.find(key);
        return it == object.end() ? nullptr : &*it;
    }
    uint64_t unsignedOr(const char* key, uint64_t fallback) const {
        const GltfJson* v = find(key);
        if (!v) return fallback;
        if (!v->is_number_unsigned() && !(v->is_number_integer() && v->get<int64_t>() >= 0))
            fail(path, "{} {} must be a non-negative integer, got {}", what, key, v->dump());
        return v->get<uint64_t>();
    }
    uint64_t required(const char* key) const {
        if (!find(key)) fail(path, "{} has no {}", what, key);
        return unsignedOr(key, 0);
    }
    int index(const char* key, int fallback = -1) const {
        const uint64_t v = unsignedOr(key, uint64_t(int64_t(fallback)));
        if (find(key) && v > uint64_t(std::numeric_limits<int>::max())) fail(path, "{} {} {} is out of range", what, key, v);
        return int(v);
    }
    std::string string(const char* key) const {
        const GltfJson* v = find(key);
        if (!v) return {};
        if (!v->is_string()) fail(path, "{} {} must be a string", what, key);
        return v->get<std::string>();
    }
    const GltfJson& objectAt(const char* key) const {
        static const GltfJson empty = GltfJson::object();
        const GltfJson* v = find(key);
        if (!v) return empty;
        if (!v->is_object()) fail(path, "{} {} must be an object", what, key);
        return *v;
    }
    std::vector<double> numbers(const char* key) const {
        const GltfJson* v = find(key);
        std::vector<double> out;
        if (!v) return out;
        if (!v->is_array()) fail(path, "{} {} must be an array of numbers", what, key);
        for (const GltfJson& x : *v) {
            if (!x.is_number()) fail(path, "{} {} must be an array of numbers", what, key);
            out.push_back(x.get<double>());
        }
        return out;
    }
};

/// @brief The array member @p key of the root (empty when absent); its elements must be objects.
const GltfJson& gltfArrayOf(const std::string& path, const GltfJson& root, const char* key);

/// @brief A URI percent-decoded ("%20" is a space), the name of a file next to the model.
std::string gltfPercentDecoded(const std::string& uri);

/// @brief Decodes the base64 payload of a data URI into @p out; false for malformed text.
bool decodeGltfBase64(std::string_view text, std::vector<uint8_t>& out);

}  // namespace penumbra
