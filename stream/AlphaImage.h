#pragma once
/// @file AlphaImage.h
/// @brief Encoded images (PNG or JPEG, stb_image) reduced to 1-bit alpha maps: the decoder that
/// glTF MASK textures (GltfAlpha.h) and the generators' leaf and petal textures share, in two
/// steps so that memory is checked before anything is decoded: readAlphaImageHeader() reads the
/// header only, decodeAlphaImage() thresholds the alpha channel once.
///
/// A texel is opaque when alpha x factor >= cutoff, alpha = value / 255 (value / 65535 for a
/// 16-bit PNG); an image without an alpha channel (every JPEG) has alpha 1. Row 0 is at v = 0.

#include "stream/AlphaTable.h"

#include <cstdint>
#include <string>
#include <vector>

namespace penumbra {

/// Texels on a side beyond which an image is refused as absurd (stb_image's own limit is 2^24).
inline constexpr uint32_t kMaxAlphaImageSide = 65536;
/// Encoded image bytes read at most (a PNG of the largest accepted size compresses below this).
inline constexpr uint64_t kMaxEncodedImageBytes = 1ull << 30;

/// @brief What an image's header says.
struct AlphaImageHeader {
    int width = 0, height = 0, channels = 0;
    bool sixteen = false;
    /// Transient bytes to decode it (the pixels, twice for the decoder's own rows).
    uint64_t decodeBytes() const { return 2 * uint64_t(width) * uint64_t(height) * uint64_t(channels) * (sixteen ? 2 : 1); }
    /// Bytes of its 1-bit map.
    uint64_t bitBytes() const { return (uint64_t(width) * uint64_t(height) + 63) / 64 * 8; }
};

/// @brief Checks that @p data is a PNG or JPEG of sane size and reads its header.
/// @param mimeType shown in the message when the bytes are neither (may be empty)
/// @throw InputError naming @p where: empty, not PNG/JPEG, corrupt header, too large.
AlphaImageHeader readAlphaImageHeader(const std::vector<uint8_t>& data, const std::string& mimeType, const std::string& where);

/// @brief The 1-bit map of @p data (whose header is @p header): texel opaque when
/// alpha x @p factor >= @p cutoff. @throw InputError naming @p where when it does not decode.
AlphaMap decodeAlphaImage(const std::vector<uint8_t>& data, const AlphaImageHeader& header, double factor, double cutoff,
                          const std::string& where);

/// @brief The bytes of image file @p path (at most kMaxEncodedImageBytes).
/// @throw InputError "WHERE: PATH: ..." when it is missing, not a regular file or too large.
std::vector<uint8_t> readAlphaImageFile(const std::string& path, const std::string& where);

}  // namespace penumbra
