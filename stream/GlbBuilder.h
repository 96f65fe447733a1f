#pragma once
/// @file GlbBuilder.h
/// @brief A small writer of hand-made glTF files: the JSON document is built as it is (so any
/// material, texture, sampler or extension can be written, including deliberately wrong ones
/// for tests), and byte arrays become bufferViews and accessors of one binary buffer. Written as
/// a .glb (the BIN chunk) or as a .gltf with the buffer as a data URI. Used by the examples
/// (`penumbra make-example`) and the tests of glTF cut-outs.

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace penumbra {

class GlbBuilder {
public:
    GlbBuilder();

    /// The document; "buffers" is written by bytes().
    nlohmann::json json;

    /// @brief Appends @p size bytes (4-byte aligned) as a new bufferView; @return its index.
    int addView(const void* data, size_t size);
    /// @brief A bufferView and an accessor of @p count elements of @p type ("VEC3") and
    /// @p componentType; @return the accessor's index.
    int addAccessor(const void* data, size_t count, int componentType, const std::string& type, bool normalized = false);
    /// @brief An image stored in a bufferView with @p mimeType; @return its index.
    int addImage(const std::vector<uint8_t>& encoded, const std::string& mimeType);
    /// @brief Appends @p value to the array member @p key of the document; @return its index.
    int append(const std::string& key, nlohmann::json value);

    /// @brief The file's bytes: a .glb when @p binary, else .gltf text with a data URI buffer.
    std::vector<uint8_t> bytes(bool binary) const;
    /// @brief Writes bytes() to @p path atomically (binary unless the name ends in .gltf).
    /// @throw InputError naming @p path when the write fails.
    void write(const std::string& path) const;

private:
    std::vector<uint8_t> bin_;
};

/// @brief @p bytes as base64 text (for data: URIs).
std::string encodeBase64(const std::vector<uint8_t>& bytes);

/// @brief @p width x @p height RGBA texels (row 0 first) encoded as a PNG.
std::vector<uint8_t> encodePngRgba(int width, int height, const std::vector<uint8_t>& rgba);

}  // namespace penumbra
