#include "bake/output/ImageWriters.h"

#include "stream/AtomicFile.h"
#include "stream/Error.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfCompression.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <stb/stb_image_write.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <set>

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

struct ExrStripWriter::State {
    std::string path;
    int width = 0, height = 0, written = 0;
    std::vector<std::string> names;
    Imf::Header header;
    AtomicFile file;
    std::unique_ptr<Imf::OutputFile> out;
    State(const std::string& p, int w, int h) : path(p), width(w), height(h), header(w, h), file(p) {}
};

ExrStripWriter::ExrStripWriter(const std::string& path, int width, int height, std::span<const std::string> channelNames,
                               std::span<const ExrAttribute> stringAttributes) {
    checkSize(path, width, height);
    if (channelNames.empty()) fail(path, "cannot write an EXR without channels");
    Imf::Header header(width, height);
    header.compression() = Imf::ZIP_COMPRESSION;  // lossless, and 16-line blocks read fast
    header.lineOrder() = Imf::INCREASING_Y;
    for (const std::string& name : channelNames) {
        if (name.empty()) fail(path, "EXR channel names must not be empty");
        // ChannelList is a sorted map, which is the order OpenEXR requires on disk; all we
        // must prevent is one name silently replacing another.
        if (header.channels().findChannel(name)) fail(path, "EXR channel '{}' is given twice", name);
        header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    }
    for (const ExrAttribute& a : stringAttributes) {
        if (a.name.empty()) fail(path, "EXR attribute names must not be empty");
        if (isReservedAttribute(a.name) || header.find(a.name) != header.end())
            fail(path, "EXR attribute '{}' clashes with a standard or earlier attribute", a.name);
        header.insert(a.name, Imf::StringAttribute(a.value));
    }
    state_ = std::make_unique<State>(path, width, height);
    state_->names.assign(channelNames.begin(), channelNames.end());
    state_->header = header;
    try {
        state_->out = std::make_unique<Imf::OutputFile>(state_->file.tempPath().c_str(), state_->header);
    } catch (const std::exception& e) {
        fail(path, "cannot write EXR: {}", withFinalPath(e.what(), state_->file));
    }
}

ExrStripWriter::~ExrStripWriter() = default;

void ExrStripWriter::write(int rows, std::span<const float* const> channels) {
    State& s = *state_;
    if (channels.size() != s.names.size())
        fail(s.path, "EXR strip has {} channels, the file {}", channels.size(), s.names.size());
    if (rows <= 0 || s.written + rows > s.height) fail(s.path, "EXR strip of {} rows does not fit the image", rows);
    const size_t rowStride = sizeof(float) * size_t(s.width);
    const Imath::Box2i strip(Imath::V2i(0, s.written), Imath::V2i(s.width - 1, s.written + rows - 1));
    Imf::FrameBuffer frame;
    for (size_t c = 0; c < channels.size(); ++c) {
        if (!channels[c]) fail(s.path, "EXR channel '{}' has no data", s.names[c]);
        // OpenEXR only reads through the slice; the cast is forced by its API. Slice::Make places
        // the strip's first row at y = written.
        frame.insert(s.names[c], Imf::Slice::Make(Imf::FLOAT, const_cast<float*>(channels[c]), strip, sizeof(float), rowStride));
    }
    try {
        s.out->setFrameBuffer(frame);
        s.out->writePixels(rows);
    } catch (const InputError&) {
        throw;
    } catch (const std::exception& e) {
        fail(s.path, "cannot write EXR: {}", withFinalPath(e.what(), s.file));
    }
    s.written += rows;
}

void ExrStripWriter::commit() {
    State& s = *state_;
    if (s.written != s.height) fail(s.path, "EXR has {} of its {} rows", s.written, s.height);
    try {
        s.out.reset();  // the OutputFile must be destroyed (flushing its line offset table) before commit()
    } catch (const std::exception& e) {
        fail(s.path, "cannot write EXR: {}", withFinalPath(e.what(), s.file));
    }
    s.file.commit();
}

void writeExr(const std::string& path, int width, int height, std::span<const ExrChannel> channels,
              std::span<const ExrAttribute> stringAttributes) {
    checkSize(path, width, height);
    std::vector<std::string> names;
    std::vector<const float*> data;
    for (const ExrChannel& c : channels) names.push_back(c.name), data.push_back(c.data);
    ExrStripWriter writer(path, width, height, names, stringAttributes);
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
            if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute()))
                image.attributes[it.name()] = s->value();
        return image;
    } catch (const InputError&) {
        throw;
    } catch (const std::exception& e) {
        fail(path, "cannot read EXR: {}", e.what());
    }
}

}  // namespace penumbra
