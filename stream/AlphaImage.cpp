#include "stream/AlphaImage.h"

#include "stream/util/Error.h"
#include "stream/util/InputFile.h"
#include "stream/util/RegularFile.h"

#include <stb/stb_image.h>

#include <cstring>
#include <memory>

namespace penumbra {

AlphaImageHeader readAlphaImageHeader(const std::vector<uint8_t>& data, const std::string& mimeType, const std::string& where) {
    static const uint8_t png[] = {0x89, 'P', 'N', 'G'}, jpeg[] = {0xFF, 0xD8, 0xFF};
    const bool isPng = data.size() >= 4 && std::memcmp(data.data(), png, 4) == 0;
    const bool isJpeg = data.size() >= 3 && std::memcmp(data.data(), jpeg, 3) == 0;
    if (data.empty()) fail(where, "is empty");
    if (!isPng && !isJpeg)
        fail(where, "is not a PNG or JPEG image{} (penumbra decodes only those)",
             mimeType.empty() ? "" : fmt::format(" (mimeType \"{}\")", mimeType));
    AlphaImageHeader h;
    if (data.size() > size_t(INT32_MAX) ||
        !stbi_info_from_memory(data.data(), int(data.size()), &h.width, &h.height, &h.channels))
        fail(where, "is corrupt ({})", stbi_failure_reason() ? stbi_failure_reason() : "unreadable header");
    if (h.width <= 0 || h.height <= 0 || uint32_t(h.width) > kMaxAlphaImageSide || uint32_t(h.height) > kMaxAlphaImageSide)
        fail(where, "is {} x {} texels; penumbra takes 1 to {} texels on a side", h.width, h.height, kMaxAlphaImageSide);
    h.sixteen = stbi_is_16_bit_from_memory(data.data(), int(data.size())) != 0;
    return h;
}

AlphaMap decodeAlphaImage(const std::vector<uint8_t>& data, const AlphaImageHeader& header, double factor, double cutoff,
                          const std::string& where) {
    int w = 0, h = 0, channels = 0;
    void* pixels = header.sixteen ? static_cast<void*>(stbi_load_16_from_memory(data.data(), int(data.size()), &w, &h, &channels, 0))
                                  : static_cast<void*>(stbi_load_from_memory(data.data(), int(data.size()), &w, &h, &channels, 0));
    if (!pixels) fail(where, "does not decode ({})", stbi_failure_reason() ? stbi_failure_reason() : "corrupt data");
    std::unique_ptr<void, void (*)(void*)> owned(pixels, stbi_image_free);
    if (w != header.width || h != header.height) fail(where, "decodes to {} x {} texels, its header says {} x {}", w, h, header.width, header.height);
    AlphaMap map;
    map.width = uint32_t(w), map.height = uint32_t(h);
    map.bits.assign((size_t(w) * size_t(h) + 63) / 64, 0);
    const bool hasAlpha = channels == 2 || channels == 4;
    const double maxValue = header.sixteen ? 65535.0 : 255.0;
    for (size_t k = 0; k < size_t(w) * size_t(h); ++k) {
        double alpha = 1.0;
        if (hasAlpha) {
            const size_t at = k * size_t(channels) + size_t(channels - 1);
            alpha = (header.sixteen ? double(static_cast<const uint16_t*>(pixels)[at]) : double(static_cast<const uint8_t*>(pixels)[at])) / maxValue;
        }
        if (alpha * factor >= cutoff) map.bits[k >> 6] |= 1ull << (k & 63);
    }
    return map;
}

std::vector<uint8_t> readAlphaImageFile(const std::string& path, const std::string& where) {
    std::vector<uint8_t> out;
    try {
        checkInputFile(path);
        RegularFile f(path);
        if (f.size() > kMaxEncodedImageBytes) fail(path, "{} bytes, more than an image may", f.size());
        out.resize(size_t(f.size()));
        f.read(out.data(), out.size(), 0);
    } catch (const InputError& e) {
        fail(where, "{}", e.what());
    }
    return out;
}

}  // namespace penumbra
