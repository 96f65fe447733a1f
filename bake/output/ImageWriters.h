#pragma once
/// @file ImageWriters.h
/// @brief Writing (and, for tests and `penumbra compare`, reading) the baked images.
///
/// Both writers go through AtomicFile: the libraries write to the temporary path by name and
/// the file is renamed into place only after they report success, so an interrupted bake
/// never leaves a truncated EXR or PNG where a previous good one was.

#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

/// One channel of an EXR being written: @p data points at width*height floats, row-major,
/// top row first.
struct ExrChannel {
    std::string name;
    const float* data;
};

/// A string attribute stored in the EXR header (provenance: scene hash, version, settings).
struct ExrAttribute {
    std::string name;
    std::string value;
};

/// @brief Writes a scanline OpenEXR file with 32-bit FLOAT channels and ZIP compression.
///
/// Channels may be given in any order (OpenEXR stores them sorted by name).
/// @param path final file path; its directory must exist.
/// @param width,height image size in pixels (both > 0).
/// @param channels at least one, with distinct non-empty names.
/// @param stringAttributes extra header attributes; names must not clash with the standard
///        header attributes (channels, compression, dataWindow, ...) or each other.
/// @throw InputError naming @p path for invalid arguments, an OpenEXR (Iex) error or an I/O
///        failure; no file is left at @p path or next to it in that case.
void writeExr(const std::string& path, int width, int height, std::span<const ExrChannel> channels,
              std::span<const ExrAttribute> stringAttributes = {});

/// @brief Writes a scanline OpenEXR (32-bit FLOAT channels, ZIP) strip by strip, top to bottom,
/// so that no full-frame array is needed: the caller fills a few rows of every channel at a
/// time. Same checks and messages as writeExr(), which is this writer with one strip.
class ExrStripWriter {
public:
    /// @param channelNames at least one, distinct and non-empty, in the order write() takes them.
    /// @throw InputError naming @p path as writeExr() does.
    ExrStripWriter(const std::string& path, int width, int height, std::span<const std::string> channelNames,
                   std::span<const ExrAttribute> stringAttributes = {});
    ~ExrStripWriter();
    ExrStripWriter(const ExrStripWriter&) = delete;
    ExrStripWriter& operator=(const ExrStripWriter&) = delete;

    /// @brief Writes the next @p rows rows; @p channels[c] points at rows x width floats of
    /// channel c (in the constructor's order), row-major.
    void write(int rows, std::span<const float* const> channels);
    /// @brief Finishes the file and renames it into place; every row must have been written.
    void commit();

private:
    struct State;
    std::unique_ptr<State> state_;
};

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
    std::map<std::string, std::vector<float>> channels;   ///< width*height floats each, top row first
    std::map<std::string, std::string> attributes;        ///< the string attributes only
};

/// @brief Reads every channel of a scanline or tiled EXR, converting HALF/UINT to float.
/// @throw InputError naming @p path when the file is missing or not a readable EXR.
ExrImage readExr(const std::string& path);

}  // namespace penumbra
