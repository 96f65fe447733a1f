#include "bake/output/ImageWriters.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfCompression.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFloatVectorAttribute.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfTiledOutputFile.h>
#include <OpenEXR/ImfVecAttribute.h>
#include <Imath/half.h>
#include <stb/stb_image_write.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <optional>
#include <set>
#include <type_traits>

namespace penumbra {

namespace {

/// Library messages mention the temporary file; users only know the final path.
std::string withFinalPath(std::string message, const AtomicFile& file) {
    const std::string& temp = file.tempPath();
    for (size_t at = message.find(temp); at != std::string::npos; at = message.find(temp, at))
        message.replace(at, temp.size(), file.finalPath()), at += file.finalPath().size();
    return message;
}

/// Header attribute names OpenEXR defines itself (single- and multi-part); a user string
/// attribute with one of these names would corrupt or be rejected by the file.
bool isReservedAttribute(const std::string& name) {
    static const std::set<std::string> kReserved = {
        "channels", "compression", "dataWindow", "displayWindow", "lineOrder",
        "pixelAspectRatio", "screenWindowCenter", "screenWindowWidth", "tiles", "type",
        "name", "version", "chunkCount", "view", "multiView"};
    return kReserved.count(name) != 0;
}

void checkSize(const std::string& path, int width, int height) {
    if (width <= 0 || height <= 0) fail(path, "cannot write a {}x{} image", width, height);
    if (static_cast<uint64_t>(width) * static_cast<uint64_t>(height) >
        static_cast<uint64_t>(std::numeric_limits<int>::max()))
        fail(path, "image {}x{} is too large", width, height);
}

}  // namespace

namespace {

/// Inserts one typed attribute; the type is the one OpenEXR readers look for.
void insertAttribute(Imf::Header& header, const ExrAttribute& a) {
    std::visit(
        [&](const auto& v) {
            using T = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<T, std::string>) header.insert(a.name, Imf::StringAttribute(v));
            else if constexpr (std::is_same_v<T, int>) header.insert(a.name, Imf::IntAttribute(v));
            else if constexpr (std::is_same_v<T, float>) header.insert(a.name, Imf::FloatAttribute(v));
            else if constexpr (std::is_same_v<T, glm::vec3>) header.insert(a.name, Imf::V3fAttribute(Imath::V3f(v.x, v.y, v.z)));
            else if constexpr (std::is_same_v<T, std::vector<float>>) header.insert(a.name, Imf::FloatVectorAttribute(v));
            else {
                Imath::M44f m;
                for (int r = 0; r < 4; ++r)
                    for (int c = 0; c < 4; ++c) m[r][c] = v.m[size_t(r)][size_t(c)];
                header.insert(a.name, Imf::M44fAttribute(m));
            }
        },
        a.value);
}

Imf::Header makeHeader(const std::string& path, int width, int height, std::span<const ExrChannelSpec> channels,
                       std::span<const ExrAttribute> attributes, const ExrFormat& format) {
    checkSize(path, width, height);
    if (channels.empty()) fail(path, "cannot write an EXR without channels");
    if (format.tileSize < 0 || format.tileSize > (1 << 16)) fail(path, "EXR tile size {} is out of range", format.tileSize);
    Imf::Header header(width, height);
    static constexpr Imf::Compression kCompression[] = {Imf::NO_COMPRESSION,    Imf::RLE_COMPRESSION,  Imf::ZIPS_COMPRESSION,
                                                        Imf::ZIP_COMPRESSION,   Imf::PIZ_COMPRESSION,  Imf::PXR24_COMPRESSION,
                                                        Imf::B44_COMPRESSION,   Imf::B44A_COMPRESSION, Imf::DWAA_COMPRESSION,
                                                        Imf::DWAB_COMPRESSION};
    header.compression() = kCompression[size_t(format.compression)];
    if (format.zipLevel != 0) {
        if (format.zipLevel < 1 || format.zipLevel > 9) fail(path, "EXR zip level {} is not in 1..9", format.zipLevel);
        header.zipCompressionLevel() = format.zipLevel;
    }
    header.lineOrder() = Imf::INCREASING_Y;
    if (format.tileSize > 0) header.setTileDescription(Imf::TileDescription(unsigned(format.tileSize), unsigned(format.tileSize), Imf::ONE_LEVEL));
    for (const ExrChannelSpec& c : channels) {
        if (c.name.empty()) fail(path, "EXR channel names must not be empty");
        // ChannelList is a sorted map, which is the order OpenEXR requires on disk; all we
        // must prevent is one name silently replacing another.
        if (header.channels().findChannel(c.name)) fail(path, "EXR channel '{}' is given twice", c.name);
        header.channels().insert(c.name, Imf::Channel(format.half && !c.keepFloat ? Imf::HALF : Imf::FLOAT));
    }
    for (const ExrAttribute& a : attributes) {
        if (a.name.empty()) fail(path, "EXR attribute names must not be empty");
        if (isReservedAttribute(a.name) || header.find(a.name) != header.end())
            fail(path, "EXR attribute '{}' clashes with a standard or earlier attribute", a.name);
        insertAttribute(header, a);
    }
    return header;
}

}  // namespace

struct ExrStripWriter::State {
    std::string path;
    int width = 0, height = 0, written = 0, tile = 0;
    std::vector<std::string> names;
    /// Channels stored as HALF: OpenEXR's tiled writer converts no pixel types, so the strip's
    /// floats are rounded here (the same round-to-nearest-even as its scanline writer).
    std::vector<bool> half;
    mutable std::vector<Imath::half> halves;
    AtomicFile file;
    std::unique_ptr<Imf::OutputFile> scanlines;
    std::unique_ptr<Imf::TiledOutputFile> tiles;
    /// Tiled files: the rows of the current row of tiles gathered so far, channel after channel.
    std::vector<float> pending;
    int pendingRows = 0;
    State(const std::string& p, int w, int h) : path(p), width(w), height(h), file(p) {}

    /// Points a frame buffer at rows [y0, y0 + rows) of every channel in @p data.
    Imf::FrameBuffer frame(int y0, int rows, std::span<const float* const> data) const {
        const size_t rowStride = sizeof(float) * size_t(width);
        const Imath::Box2i strip(Imath::V2i(0, y0), Imath::V2i(width - 1, y0 + rows - 1));
        Imf::FrameBuffer frame;
        const size_t pixels = size_t(rows) * size_t(width);
        halves.resize(size_t(std::count(half.begin(), half.end(), true)) * pixels);
        size_t next = 0;
        for (size_t c = 0; c < names.size(); ++c) {
            if (half[c]) {
                Imath::half* h = &halves[next * pixels];
                std::copy(data[c], data[c] + pixels, h);
                ++next;
                frame.insert(names[c], Imf::Slice::Make(Imf::HALF, h, strip, sizeof(Imath::half), sizeof(Imath::half) * size_t(width)));
                continue;
            }
            // OpenEXR only reads through the slice; the cast is forced by its API. Slice::Make
            // places the strip's first row at y = y0.
            frame.insert(names[c], Imf::Slice::Make(Imf::FLOAT, const_cast<float*>(data[c]), strip, sizeof(float), rowStride));
        }
        return frame;
    }
    /// Writes the gathered row of tiles.
    void flushTiles() {
        const int y0 = written - pendingRows;
        std::vector<const float*> data;
        for (size_t c = 0; c < names.size(); ++c) data.push_back(&pending[c * size_t(tile) * size_t(width)]);
        tiles->setFrameBuffer(frame(y0, pendingRows, data));
        tiles->writeTiles(0, tiles->numXTiles() - 1, y0 / tile, y0 / tile);
        pendingRows = 0;
    }
};

ExrStripWriter::ExrStripWriter(const std::string& path, int width, int height, std::span<const ExrChannelSpec> channels,
                               std::span<const ExrAttribute> attributes, const ExrFormat& format) {
    Imf::Header header = makeHeader(path, width, height, channels, attributes, format);
    state_ = std::make_unique<State>(path, width, height);
    State& s = *state_;
    for (const ExrChannelSpec& c : channels) s.names.push_back(c.name), s.half.push_back(format.half && !c.keepFloat);
    s.tile = format.tileSize;
    try {
        if (s.tile > 0) {
            s.tiles = std::make_unique<Imf::TiledOutputFile>(s.file.tempPath().c_str(), header);
            s.pending.assign(s.names.size() * size_t(s.tile) * size_t(width), 0.f);
        } else {
            s.scanlines = std::make_unique<Imf::OutputFile>(s.file.tempPath().c_str(), header);
        }
    } catch (const std::exception& e) {
        fail(path, "cannot write EXR: {}", withFinalPath(e.what(), s.file));
    }
}

ExrStripWriter::~ExrStripWriter() = default;

void setExrCompressionThreads(int threads) {
    if (Imf::globalThreadCount() != std::max(threads, 0)) Imf::setGlobalThreadCount(std::max(threads, 0));
}

int exrLinesPerBlock(ExrCompression compression) {
    switch (compression) {
        case ExrCompression::None:
        case ExrCompression::Rle:
        case ExrCompression::Zips: return 1;
        case ExrCompression::Zip:
        case ExrCompression::Pxr24: return 16;
        case ExrCompression::Piz:
        case ExrCompression::B44:
        case ExrCompression::B44a:
        case ExrCompression::Dwaa: return 32;
        case ExrCompression::Dwab: return 256;
    }
    return 256;
}

uint64_t ExrStripWriter::bytes(int width, size_t channels, const ExrFormat& format) {
    // OpenEXR keeps a block (exrLinesPerBlock() lines, or one row of tiles) uncompressed and
    // compressed. Its thread pool keeps two per thread, but bakes that plan their memory compress
    // without it (runBake()), and this is what they plan.
    const uint64_t rows = format.tileSize > 0 ? uint64_t(format.tileSize) : uint64_t(exrLinesPerBlock(format.compression));
    // DWA keeps its planar and DCT buffers besides the two copies; four covers them.
    const bool dwa = format.compression == ExrCompression::Dwaa || format.compression == ExrCompression::Dwab;
    const uint64_t block = (dwa ? 4 : 2) * rows * channels * uint64_t(width) * 4;
    // HALF channels: the strip's rounded copy (at most 64 rows or one row of tiles, 2 bytes each).
    const uint64_t halves = format.half ? std::max<uint64_t>(rows, 64) * channels * uint64_t(width) * 2 : 0;
    return block + halves + (format.tileSize > 0 ? rows * channels * uint64_t(width) * 4 : 0);
}

void ExrStripWriter::write(int rows, std::span<const float* const> channels) {
    State& s = *state_;
    if (channels.size() != s.names.size())
        fail(s.path, "EXR strip has {} channels, the file {}", channels.size(), s.names.size());
    if (rows <= 0 || s.written + rows > s.height) fail(s.path, "EXR strip of {} rows does not fit the image", rows);
    for (size_t c = 0; c < channels.size(); ++c)
        if (!channels[c]) fail(s.path, "EXR channel '{}' has no data", s.names[c]);
    try {
        if (s.scanlines) {
            s.scanlines->setFrameBuffer(s.frame(s.written, rows, channels));
            s.scanlines->writePixels(rows);
            s.written += rows;
            return;
        }
        const size_t W = size_t(s.width);
        for (int y = 0; y < rows; ++y) {
            for (size_t c = 0; c < channels.size(); ++c)
                std::memcpy(&s.pending[(c * size_t(s.tile) + size_t(s.pendingRows)) * W], channels[c] + size_t(y) * W, W * sizeof(float));
            ++s.pendingRows, ++s.written;
            if (s.pendingRows == s.tile || s.written == s.height) s.flushTiles();
        }
    } catch (const InputError&) {
        throw;
    } catch (const std::exception& e) {
        fail(s.path, "cannot write EXR: {}", withFinalPath(e.what(), s.file));
    }
}

void ExrStripWriter::commit() {
    State& s = *state_;
    if (s.written != s.height) fail(s.path, "EXR has {} of its {} rows", s.written, s.height);
    try {
        // The file object must be destroyed (flushing its offset table) before commit().
        s.scanlines.reset();
        s.tiles.reset();
    } catch (const std::exception& e) {
        fail(s.path, "cannot write EXR: {}", withFinalPath(e.what(), s.file));
    }
    s.file.commit();
}

void writeExr(const std::string& path, int width, int height, std::span<const ExrChannel> channels,
              std::span<const ExrAttribute> attributes, const ExrFormat& format) {
    checkSize(path, width, height);
    std::vector<ExrChannelSpec> specs;
    std::vector<const float*> data;
    for (const ExrChannel& c : channels) specs.push_back({c.name, c.keepFloat}), data.push_back(c.data);
    ExrStripWriter writer(path, width, height, specs, attributes, format);
    writer.write(height, data);
    writer.commit();
}

void writePng8(const std::string& path, int width, int height, int channels,
               std::span<const uint8_t> pixels) {
    checkSize(path, width, height);
    if (channels < 1 || channels > 4) fail(path, "a PNG has 1 to 4 channels, not {}", channels);
    const uint64_t expected = static_cast<uint64_t>(width) * static_cast<uint64_t>(height) *
                              static_cast<uint64_t>(channels);
    if (pixels.size() != expected)
        fail(path, "PNG {}x{}x{} needs {} bytes but {} were given", width, height, channels,
             expected, pixels.size());
    if (static_cast<uint64_t>(width) * static_cast<uint64_t>(channels) >
        static_cast<uint64_t>(std::numeric_limits<int>::max()))
        fail(path, "PNG rows of {} pixels are too wide", width);

    // stbi_write_png() ignores fwrite errors (a full disk would pass as success), so the
    // encoded bytes are handed to AtomicFile, which checks every write and the close.
    // Exceptions must not unwind through stb's C frames: the callback parks them instead.
    struct Sink {
        AtomicFile* file;
        std::exception_ptr error;
    };
    AtomicFile file(path);
    Sink sink{&file, nullptr};
    auto callback = [](void* context, void* data, int size) {
        auto* s = static_cast<Sink*>(context);
        if (s->error || size <= 0) return;
        try {
            s->file->write(data, static_cast<size_t>(size));
        } catch (...) {
            s->error = std::current_exception();
        }
    };
    int ok = stbi_write_png_to_func(callback, &sink, width, height, channels, pixels.data(),
                                    width * channels);
    if (sink.error) std::rethrow_exception(sink.error);
    if (!ok) fail(path, "PNG encoding failed (out of memory?)");
    file.commit();
}

// ---------------------------------------------------------------------------------------------
// PNG in strips: the signature, IHDR, the zlib stream of filtered rows cut into IDAT chunks, IEND.

struct PngStripWriter::State {
    std::string path;
    int width = 0, height = 0, channels = 0, written = 0;
    AtomicFile file;
    z_stream zip{};
    bool zipOpen = false;
    std::vector<uint8_t> out, row, previous;
    State(const std::string& p) : path(p), file(p) {}
    ~State() {
        if (zipOpen) deflateEnd(&zip);
    }

    void chunk(const char type[4], const uint8_t* data, size_t size) {
        uint8_t head[8] = {uint8_t(size >> 24), uint8_t(size >> 16), uint8_t(size >> 8), uint8_t(size), 0, 0, 0, 0};
        std::memcpy(head + 4, type, 4);
        uLong crc = crc32(0L, head + 4, 4);
        if (size) crc = crc32(crc, data, uInt(size));
        const uint8_t tail[4] = {uint8_t(crc >> 24), uint8_t(crc >> 16), uint8_t(crc >> 8), uint8_t(crc)};
        file.write(head, 8);
        if (size) file.write(data, size);
        file.write(tail, 4);
    }
    /// Deflates @p size bytes (or finishes the stream), emitting an IDAT whenever the buffer fills.
    void deflateBytes(const uint8_t* data, size_t size, int flush) {
        zip.next_in = const_cast<Bytef*>(data);
        zip.avail_in = uInt(size);
        for (;;) {
            zip.next_out = out.data() + (out.size() - zip.avail_out);
            const int status = deflate(&zip, flush);
            if (status == Z_STREAM_ERROR) fail(path, "PNG encoding failed (zlib)");
            if (zip.avail_out == 0) {
                chunk("IDAT", out.data(), out.size());
                zip.avail_out = uInt(out.size());
                continue;
            }
            if (zip.avail_in == 0 && (flush == Z_NO_FLUSH || status == Z_STREAM_END)) break;
        }
    }
};

PngStripWriter::PngStripWriter(const std::string& path, int width, int height, int channels) {
    checkSize(path, width, height);
    if (channels < 1 || channels > 4) fail(path, "a PNG has 1 to 4 channels, not {}", channels);
    state_ = std::make_unique<State>(path);
    State& s = *state_;
    s.width = width, s.height = height, s.channels = channels;
    if (deflateInit(&s.zip, 6) != Z_OK) fail(path, "PNG encoding failed (zlib could not start)");
    s.zipOpen = true;
    s.out.resize(64 * 1024);
    s.zip.avail_out = uInt(s.out.size());
    s.row.resize(size_t(width) * size_t(channels) + 1);
    static const uint8_t signature[8] = {137, 80, 78, 71, 13, 10, 26, 10};
    s.file.write(signature, 8);
    static const uint8_t colourType[5] = {0, 0, 4, 2, 6};
    const uint8_t ihdr[13] = {uint8_t(width >> 24), uint8_t(width >> 16), uint8_t(width >> 8), uint8_t(width),
                              uint8_t(height >> 24), uint8_t(height >> 16), uint8_t(height >> 8), uint8_t(height),
                              8, colourType[channels], 0, 0, 0};
    s.chunk("IHDR", ihdr, sizeof ihdr);
}

PngStripWriter::~PngStripWriter() = default;

uint64_t PngStripWriter::bytes(int width, int channels) {
    // zlib's deflate at level 6 (about 268 KiB of windows and hash tables), the 64 KiB output
    // buffer and one filtered row.
    return (268u << 10) + (64u << 10) + 2 * (uint64_t(width) * uint64_t(channels) + 1);
}

void PngStripWriter::write(int rows, std::span<const uint8_t> pixels) {
    State& s = *state_;
    const size_t rowBytes = size_t(s.width) * size_t(s.channels);
    if (rows < 0 || s.written + rows > s.height || pixels.size() != rowBytes * size_t(rows))
        fail(s.path, "PNG strip of {} rows ({} bytes) does not fit the {}x{} image", rows, pixels.size(), s.width, s.height);
    for (int y = 0; y < rows; ++y) {
        // Filter 1 (Sub): each byte minus the one a pixel to its left; cheap, and it compresses
        // smooth shading well.
        const uint8_t* in = pixels.data() + size_t(y) * rowBytes;
        s.row[0] = 1;
        for (size_t i = 0; i < rowBytes; ++i)
            s.row[i + 1] = uint8_t(in[i] - (i >= size_t(s.channels) ? in[i - size_t(s.channels)] : 0));
        s.deflateBytes(s.row.data(), s.row.size(), Z_NO_FLUSH);
    }
    s.written += rows;
}

void PngStripWriter::commit() {
    State& s = *state_;
    if (s.written != s.height) fail(s.path, "PNG has {} of its {} rows", s.written, s.height);
    s.deflateBytes(nullptr, 0, Z_FINISH);
    const size_t pending = s.out.size() - s.zip.avail_out;
    if (pending) s.chunk("IDAT", s.out.data(), pending);
    s.chunk("IEND", nullptr, 0);
    deflateEnd(&s.zip);
    s.zipOpen = false;
    s.file.commit();
}

uint8_t encodeSrgb(float linear) {
    if (!(linear > 0.0f)) return 0;  // negative, zero and NaN
    if (linear >= 1.0f) return 255;
    float s = linear <= 0.0031308f ? 12.92f * linear
                                   : 1.055f * std::pow(linear, 1.0f / 2.4f) - 0.055f;
    return static_cast<uint8_t>(s * 255.0f + 0.5f);
}

namespace {

/// An attribute as an ExrValue, when it is of one of the kinds ExrValue holds.
std::optional<ExrValue> valueOf(const Imf::Attribute& a) {
    if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&a)) return s->value();
    if (const auto* i = dynamic_cast<const Imf::IntAttribute*>(&a)) return i->value();
    if (const auto* f = dynamic_cast<const Imf::FloatAttribute*>(&a)) return f->value();
    if (const auto* v = dynamic_cast<const Imf::V3fAttribute*>(&a)) return glm::vec3(v->value().x, v->value().y, v->value().z);
    if (const auto* fv = dynamic_cast<const Imf::FloatVectorAttribute*>(&a)) return fv->value();
    if (const auto* m = dynamic_cast<const Imf::M44fAttribute*>(&a)) {
        ExrMatrix out;
        for (int r = 0; r < 4; ++r)
            for (int c = 0; c < 4; ++c) out.m[size_t(r)][size_t(c)] = m->value()[r][c];
        return out;
    }
    return std::nullopt;
}

}  // namespace

ExrImage readExr(const std::string& path) {
    try {
        Imf::InputFile in(path.c_str());
        const Imf::Header& header = in.header();
        const Imath::Box2i dw = header.dataWindow();
        ExrImage image;
        image.width = dw.max.x - dw.min.x + 1;
        image.height = dw.max.y - dw.min.y + 1;
        if (image.width <= 0 || image.height <= 0) fail(path, "EXR has an empty data window");
        const size_t pixels = static_cast<size_t>(image.width) * static_cast<size_t>(image.height);

        Imf::FrameBuffer frame;
        for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
            if (it.channel().xSampling != 1 || it.channel().ySampling != 1)
                fail(path, "EXR channel '{}' is subsampled, which is not supported", it.name());
            static const char* kTypes[] = {"uint", "half", "float"};
            image.channelTypes[it.name()] = kTypes[std::clamp(int(it.channel().type), 0, 2)];
            std::vector<float>& dst = image.channels[it.name()];
            dst.assign(pixels, 0.0f);
            // Slice::Make offsets the base pointer for a data window not starting at (0, 0)
            // without us doing out-of-bounds pointer arithmetic.
            frame.insert(it.name(), Imf::Slice::Make(Imf::FLOAT, dst.data(), dw, sizeof(float),
                                                      sizeof(float) * static_cast<size_t>(image.width)));
        }
        in.setFrameBuffer(frame);
        in.readPixels(dw.min.y, dw.max.y);

        for (auto it = header.begin(); it != header.end(); ++it)
            if (std::optional<ExrValue> value = valueOf(it.attribute())) image.attributes[it.name()] = *value;
        if (header.hasTileDescription())
            image.tileWidth = int(header.tileDescription().xSize), image.tileHeight = int(header.tileDescription().ySize);
        return image;
    } catch (const InputError&) {
        throw;
    } catch (const std::exception& e) {
        fail(path, "cannot read EXR: {}", e.what());
    }
}

}  // namespace penumbra
