#pragma once
/// @file ImageWriters.h
/// @brief Writing (and, for tests and `penumbra compare`, reading) the baked images.
///
/// Both writers go through AtomicFile: the libraries write to the temporary path by name and
/// the file is renamed into place only after they report success, so an interrupted bake
/// never leaves a truncated EXR or PNG where a previous good one was.

#include "stream/util/Error.h"

#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <variant>
#include <vector>

namespace penumbra {

/// @brief A 4x4 matrix as OpenEXR stores it (Imath::M44f): m[row][column], row vectors, so a
/// point p maps to (p, 1) * m (the translation is in the bottom row).
struct ExrMatrix {
    std::array<std::array<float, 4>, 4> m{};
};

/// The value of a header attribute: string, int, float, v3f, m44f or a float vector.
using ExrValue = std::variant<std::string, int, float, glm::vec3, ExrMatrix, std::vector<float>>;

/// One header attribute (provenance, settings, camera matrices), stored with its own type.
struct ExrAttribute {
    std::string name;
    ExrValue value;
};

/// One channel of an EXR being written: @p data points at width*height floats, row-major,
/// top row first. @p keepFloat: stays 32-bit FLOAT in a half-float file (depth).
struct ExrChannel {
    std::string name;
    const float* data;
    bool keepFloat = false;
};

/// A channel's name and storage for ExrStripWriter.
struct ExrChannelSpec {
    std::string name;
    bool keepFloat = false;  ///< stays 32-bit FLOAT when ExrFormat::half is set
};

/// OpenEXR's compression methods (exr.compression). Lossless: None, Rle, Zips (one line a
/// block), Zip (16 lines, the default), Piz (wavelet, 32 lines). Lossy: Pxr24 (FLOAT rounded to
/// 24 bits), B44 and B44a (HALF channels only; FLOAT ones are stored as they are), Dwaa and Dwab
/// (DCT, 32 and 256 lines).
enum class ExrCompression { None, Rle, Zips, Zip, Piz, Pxr24, B44, B44a, Dwaa, Dwab };

/// @brief Scanlines in one compressed block of a scanline file (what OpenEXR buffers per block).
int exrLinesPerBlock(ExrCompression compression);

/// How an EXR is stored: 32-bit FLOAT or 16-bit HALF channels, scanlines or square tiles, and
/// the compression (ZIP by default).
struct ExrFormat {
    bool half = false;  ///< HALF for every channel that is not marked keepFloat
    int tileSize = 0;   ///< 0: scanlines; else tiles of tileSize x tileSize pixels (one level)
    ExrCompression compression = ExrCompression::Zip;
    int zipLevel = 0;   ///< deflate level 1..9 of Zip and Zips; 0: OpenEXR's default
};

/// @brief Writes an OpenEXR file with the channels given (compression: ExrFormat).
///
/// Channels may be given in any order (OpenEXR stores them sorted by name).
/// @param path final file path; its directory must exist.
/// @param width,height image size in pixels (both > 0).
/// @param channels at least one, with distinct non-empty names.
/// @param attributes extra header attributes; names must not clash with the core header
///        attributes (channels, compression, dataWindow, ...) or each other.
/// @param format FLOAT or HALF, scanlines or tiles, the compression.
/// @throw InputError naming @p path for invalid arguments, an OpenEXR (Iex) error or an I/O
///        failure; no file is left at @p path or next to it in that case.
void writeExr(const std::string& path, int width, int height, std::span<const ExrChannel> channels,
              std::span<const ExrAttribute> attributes = {}, const ExrFormat& format = {});

/// @brief Writes an OpenEXR strip by strip, top to bottom, so that no full-frame array is
/// needed: the caller fills a few rows of every channel at a time. Same checks and messages as
/// writeExr(), which is this writer with one strip. A tiled file buffers one row of tiles
/// (tileSize rows), whatever the strips' heights.
class ExrStripWriter {
public:
    /// @param channels at least one, distinct and non-empty names, in the order write() takes them.
    /// @throw InputError naming @p path as writeExr() does.
    ExrStripWriter(const std::string& path, int width, int height, std::span<const ExrChannelSpec> channels,
                   std::span<const ExrAttribute> attributes = {}, const ExrFormat& format = {});
    ~ExrStripWriter();
    ExrStripWriter(const ExrStripWriter&) = delete;
    ExrStripWriter& operator=(const ExrStripWriter&) = delete;

    /// @brief Writes the next @p rows rows; @p channels[c] points at rows x width floats of
    /// channel c (in the constructor's order), row-major.
    void write(int rows, std::span<const float* const> channels);
    /// @brief Finishes the file and renames it into place; every row must have been written.
    void commit();
    /// @brief Heap bytes a writer of @p channels channels holds for a @p width wide image: OpenEXR's
    /// line or tile buffers (without setExrCompressionThreads(), which adds two per thread) and,
    /// when tiled, the row of tiles being gathered.
    static uint64_t bytes(int width, size_t channels, const ExrFormat& format);

private:
    struct State;
    std::unique_ptr<State> state_;
};

/// @brief Compresses the blocks of every EXR written from now on with @p threads threads of
/// OpenEXR's own pool (0: in the writing thread). The file's bytes do not change: each block is
/// compressed on its own and the blocks are written in order. Process-wide, as OpenEXR's pool is.
void setExrCompressionThreads(int threads);

/// @brief Writes an 8-bit PNG strip by strip (zlib deflate as rows arrive, one IDAT chunk per
/// 64 KiB of compressed data), so that no full-frame buffer is needed. Goes through AtomicFile.
class PngStripWriter {
public:
    /// @param channels 1 = grey, 2 = grey+alpha, 3 = RGB, 4 = RGBA
    PngStripWriter(const std::string& path, int width, int height, int channels);
    ~PngStripWriter();
    PngStripWriter(const PngStripWriter&) = delete;
    PngStripWriter& operator=(const PngStripWriter&) = delete;

    /// @brief Appends @p rows rows of width x channels bytes each, interleaved.
    void write(int rows, std::span<const uint8_t> pixels);
    /// @brief Finishes the file and renames it into place; every row must have been written.
    void commit();
    /// Heap bytes a writer holds (zlib's deflate state and the output buffer).
    static uint64_t bytes(int width, int channels);

private:
    struct State;
    std::unique_ptr<State> state_;
};

/// @brief Writes an 8-bit PNG (1 = grey, 2 = grey+alpha, 3 = RGB, 4 = RGBA channels).
/// @param pixels width*height*channels bytes, row-major, top row first, interleaved.
/// @throw InputError naming @p path for a size mismatch or when stb fails to write.
void writePng8(const std::string& path, int width, int height, int channels,
               std::span<const uint8_t> pixels);

/// @brief Encodes a linear value with the sRGB transfer function (IEC 61966-2-1) to 0..255.
/// Values are clamped to [0, 1]; NaN encodes as 0.
uint8_t encodeSrgb(float linear);

/// @brief A whole EXR image read back as float channels.
struct ExrImage {
    int width = 0;
    int height = 0;
    std::map<std::string, std::vector<float>> channels;  ///< width*height floats each, top row first
    std::map<std::string, std::string> channelTypes;     ///< "float", "half" or "uint" per channel
    /// The attributes of the kinds ExrValue holds (others, such as the core ones, are skipped).
    std::map<std::string, ExrValue> attributes;
    int tileWidth = 0, tileHeight = 0;                    ///< 0: a scanline file

    /// @brief Attribute @p name as a @p T.
    /// @throw InputError when it is missing or of another type.
    template <class T>
    const T& attribute(const std::string& name) const;
};

/// @brief Reads every channel of a scanline or tiled EXR, converting HALF/UINT to float.
/// @throw InputError naming @p path when the file is missing or not a readable EXR.
ExrImage readExr(const std::string& path);

template <class T>
const T& ExrImage::attribute(const std::string& name) const {
    auto it = attributes.find(name);
    if (it == attributes.end()) throw InputError("EXR attribute '" + name + "' is missing");
    if (const T* value = std::get_if<T>(&it->second)) return *value;
    throw InputError("EXR attribute '" + name + "' has another type");
}

}  // namespace penumbra
