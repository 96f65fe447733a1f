#include "bake/ImageWriters.h"

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

#include <cmath>
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

void writeExr(const std::string& path, int width, int height, std::span<const ExrChannel> channels,
              std::span<const ExrAttribute> stringAttributes) {
    checkSize(path, width, height);
    if (channels.empty()) fail(path, "cannot write an EXR without channels");

    Imf::Header header(width, height);
    header.compression() = Imf::ZIP_COMPRESSION;  // lossless, and 16-line blocks read fast
    header.lineOrder() = Imf::INCREASING_Y;

    const size_t rowStride = sizeof(float) * static_cast<size_t>(width);
    Imf::FrameBuffer frame;
    for (const ExrChannel& c : channels) {
        if (c.name.empty()) fail(path, "EXR channel names must not be empty");
        if (!c.data) fail(path, "EXR channel '{}' has no data", c.name);
        // ChannelList is a sorted map, which is the order OpenEXR requires on disk; all we
        // must prevent is one name silently replacing another.
        if (header.channels().findChannel(c.name))
            fail(path, "EXR channel '{}' is given twice", c.name);
        header.channels().insert(c.name, Imf::Channel(Imf::FLOAT));
        // OpenEXR only reads through the slice; the cast is forced by its API.
        frame.insert(c.name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(c.data)),
                                        sizeof(float), rowStride));
    }
    for (const ExrAttribute& a : stringAttributes) {
        if (a.name.empty()) fail(path, "EXR attribute names must not be empty");
        if (isReservedAttribute(a.name) || header.find(a.name) != header.end())
            fail(path, "EXR attribute '{}' clashes with a standard or earlier attribute", a.name);
        header.insert(a.name, Imf::StringAttribute(a.value));
    }

    AtomicFile file(path);
    try {
        // The OutputFile must be destroyed (flushing its line offset table) before commit().
        Imf::OutputFile out(file.tempPath().c_str(), header);
        out.setFrameBuffer(frame);
        out.writePixels(height);
    } catch (const InputError&) {
        throw;
    } catch (const std::exception& e) {
        fail(path, "cannot write EXR: {}", withFinalPath(e.what(), file));
    }
    file.commit();
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
