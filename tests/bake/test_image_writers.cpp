// Tests for the EXR/PNG writers, readExr and the sRGB encoder.

#include "bake/output/ImageWriters.h"
#include "stream/util/Error.h"

#include "TestSupport.h"

#include <catch2/catch.hpp>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <stb/stb_image.h>

#include <stdlib.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>

using namespace penumbra::test;
namespace fs = std::filesystem;
using penumbra::ExrAttribute;
using penumbra::ExrChannel;
using penumbra::InputError;

namespace {

bool sameBits(const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

}  // namespace

TEST_CASE("writeExr round-trips channels bit-exactly with ZIP compression and attributes", "[io]") {
    ScratchDir dir;
    const int w = 37, h = 21;  // more than one 16-line ZIP block, odd sizes
    const size_t n = static_cast<size_t>(w) * h;
    std::vector<float> y(n), a(n), shadow(n);
    for (size_t i = 0; i < n; ++i) {
        y[i] = static_cast<float>(i) * 0.37f - 50.0f;
        a[i] = std::sin(static_cast<float>(i));
        shadow[i] = static_cast<float>(i % 7) / 7.0f;
    }
    // Values a lossy or half-float path would change.
    y[0] = std::numeric_limits<float>::quiet_NaN();
    y[1] = std::numeric_limits<float>::infinity();
    y[2] = -0.0f;
    y[3] = std::numeric_limits<float>::denorm_min();
    y[4] = 1.0f + std::numeric_limits<float>::epsilon();
    y[5] = std::numeric_limits<float>::max();

    // Deliberately unsorted; OpenEXR stores channels sorted by name.
    const ExrChannel channels[] = {{"Y", y.data()}, {"A", a.data()}, {"B.shadow", shadow.data()}};
    const ExrAttribute attributes[] = {{"penumbra:version", std::string("0.1.0")},
                                       {"penumbra:scene", std::string("examples/default.json")}};
    const std::string path = dir.file("out.exr");
    penumbra::writeExr(path, w, h, channels, attributes);
    CHECK(dir.count() == 1);

    penumbra::ExrImage image = penumbra::readExr(path);
    CHECK(image.width == w);
    CHECK(image.height == h);
    std::vector<std::string> names;
    for (const auto& [name, values] : image.channels) names.push_back(name);
    CHECK(names == std::vector<std::string>{"A", "B.shadow", "Y"});
    CHECK(sameBits(image.channels["Y"], y));
    CHECK(sameBits(image.channels["A"], a));
    CHECK(sameBits(image.channels["B.shadow"], shadow));
    CHECK(image.attribute<std::string>("penumbra:version") == "0.1.0");
    CHECK(image.attribute<std::string>("penumbra:scene") == "examples/default.json");

    Imf::InputFile in(path.c_str());
    CHECK(in.header().compression() == Imf::ZIP_COMPRESSION);
    for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it)
        CHECK(it.channel().type == Imf::FLOAT);
}

TEST_CASE("writeExr stores every compression the scene can name, and the lossless ones round-trip bit-exactly", "[io]") {
    using penumbra::ExrCompression;
    ScratchDir dir;
    const int w = 67, h = 301;  // more than one block of every method (DWAB: 256 lines)
    std::vector<float> v(size_t(w) * h), z(v.size());
    for (size_t i = 0; i < v.size(); ++i) v[i] = 0.5f + 0.5f * std::sin(0.01f * float(i)), z[i] = 1.0f + float(i % 977) * 0.25f;
    const ExrChannel channels[] = {{"V", v.data()}, {"Z", z.data(), true}};
    const std::pair<ExrCompression, Imf::Compression> methods[] = {
        {ExrCompression::None, Imf::NO_COMPRESSION},   {ExrCompression::Rle, Imf::RLE_COMPRESSION},
        {ExrCompression::Zips, Imf::ZIPS_COMPRESSION}, {ExrCompression::Zip, Imf::ZIP_COMPRESSION},
        {ExrCompression::Piz, Imf::PIZ_COMPRESSION},   {ExrCompression::Pxr24, Imf::PXR24_COMPRESSION},
        {ExrCompression::B44, Imf::B44_COMPRESSION},   {ExrCompression::B44a, Imf::B44A_COMPRESSION},
        {ExrCompression::Dwaa, Imf::DWAA_COMPRESSION}, {ExrCompression::Dwab, Imf::DWAB_COMPRESSION}};
    for (const auto& [compression, stored] : methods) {
        for (const int tiles : {0, 32}) {
            penumbra::ExrFormat format;
            format.compression = compression, format.tileSize = tiles;
            const std::string path = dir.file("c.exr");
            penumbra::writeExr(path, w, h, channels, {}, format);
            INFO("method " << int(stored) << ", tiles " << tiles);
            CHECK(Imf::InputFile(path.c_str()).header().compression() == stored);
            const penumbra::ExrImage image = penumbra::readExr(path);
            const bool lossless = stored <= Imf::PIZ_COMPRESSION || stored == Imf::B44_COMPRESSION || stored == Imf::B44A_COMPRESSION;
            if (lossless) {  // B44 compresses HALF channels only: these FLOAT ones are stored as they are
                CHECK(sameBits(image.channels.at("V"), v));
                CHECK(sameBits(image.channels.at("Z"), z));
            }
            for (size_t i = 0; i < v.size(); ++i) {
                if (std::abs(image.channels.at("V")[i] - v[i]) > 0.05f) FAIL("V of pixel " << i << " is " << image.channels.at("V")[i]);
            }
            CHECK(penumbra::ExrStripWriter::bytes(w, 2, format) > 0);
        }
    }
    // The deflate level changes the bytes, not the pixels.
    penumbra::ExrFormat fast, small;
    fast.zipLevel = 1, small.zipLevel = 9;
    penumbra::writeExr(dir.file("fast.exr"), w, h, channels, {}, fast);
    penumbra::writeExr(dir.file("small.exr"), w, h, channels, {}, small);
    CHECK(fs::file_size(dir.file("fast.exr")) >= fs::file_size(dir.file("small.exr")));
    CHECK(sameBits(penumbra::readExr(dir.file("fast.exr")).channels.at("V"), penumbra::readExr(dir.file("small.exr")).channels.at("V")));
    penumbra::ExrFormat bad;
    bad.zipLevel = 10;
    CHECK_THROWS_AS(penumbra::writeExr(dir.file("bad.exr"), w, h, channels, {}, bad), InputError);
    CHECK_FALSE(fs::exists(dir.file("bad.exr")));
}

TEST_CASE("EXR files are the same bytes whether their blocks are compressed on OpenEXR's threads or not", "[io]") {
    ScratchDir dir;
    const int w = 301, h = 203;  // many 16-line blocks and rows of tiles, odd sizes
    std::vector<float> v(size_t(w) * h), z(v.size());
    for (size_t i = 0; i < v.size(); ++i) v[i] = std::sin(0.001f * float(i)), z[i] = float(i % 977) * 0.25f;
    const ExrChannel channels[] = {{"V", v.data()}, {"Z", z.data(), true}};
    penumbra::ExrFormat dwa, piz;
    dwa.compression = penumbra::ExrCompression::Dwaa, piz.compression = penumbra::ExrCompression::Piz, piz.tileSize = 64;
    for (const penumbra::ExrFormat format : {penumbra::ExrFormat{}, penumbra::ExrFormat{true, 0}, penumbra::ExrFormat{false, 64}, dwa, piz}) {
        std::vector<std::string> bytes;
        for (int threads : {0, 2, 3, 0}) {
            penumbra::setExrCompressionThreads(threads);
            const std::string path = dir.file("t" + std::to_string(bytes.size()) + ".exr");
            penumbra::writeExr(path, w, h, channels, {}, format);
            bytes.push_back(slurp(path));
        }
        penumbra::setExrCompressionThreads(0);
        INFO("half " << format.half << ", tiles " << format.tileSize);
        for (const std::string& b : bytes) CHECK(b == bytes[0]);
        CHECK(sameBits(penumbra::readExr(dir.file("t1.exr")).channels["V"], penumbra::readExr(dir.file("t0.exr")).channels["V"]));
    }
}

TEST_CASE("writeExr rejects bad arguments and leaves no file", "[io]") {
    ScratchDir dir;
    std::vector<float> px(4, 1.0f);
    const std::string path = dir.file("bad.exr");
    const ExrChannel dup[] = {{"Y", px.data()}, {"Y", px.data()}};
    CHECK(errorOf([&] { penumbra::writeExr(path, 2, 2, dup); }) == path + ": EXR channel 'Y' is given twice");
    const ExrChannel one[] = {{"Y", px.data()}};
    const ExrAttribute reserved[] = {{"compression", "none"}};
    CHECK(errorOf([&] { penumbra::writeExr(path, 2, 2, one, reserved); }).find("clashes") != std::string::npos);
    CHECK(errorOf([&] { penumbra::writeExr(path, 0, 2, one); }) == path + ": cannot write a 0x2 image");
    CHECK(errorOf([&] { penumbra::writeExr(path, 2, 2, {}); }) == path + ": cannot write an EXR without channels");
    CHECK(dir.count() == 0);
}

TEST_CASE("writeExr and writePng8 into a missing or unwritable directory", "[io]") {
    ScratchDir dir;
    std::vector<float> px(4, 0.5f);
    const ExrChannel one[] = {{"Y", px.data()}};
    const std::vector<uint8_t> grey(4, 128);

    const std::string missing = dir.file("nope/out.exr");
    CHECK(errorOf([&] { penumbra::writeExr(missing, 2, 2, one); }) ==
          missing + ": cannot create file: No such file or directory");
    const std::string missingPng = dir.file("nope/out.png");
    CHECK(errorOf([&] { penumbra::writePng8(missingPng, 2, 2, 1, grey); }) ==
          missingPng + ": cannot create file: No such file or directory");

    { std::ofstream(dir.file("plain")) << "x"; }
    const std::string underFile = dir.file("plain/out.exr");
    CHECK(errorOf([&] { penumbra::writeExr(underFile, 2, 2, one); }) ==
          underFile + ": cannot create file: Not a directory");

    if (::geteuid() != 0) {  // root ignores permissions
        fs::create_directory(dir.path / "ro");
        fs::permissions(dir.path / "ro", fs::perms::owner_read | fs::perms::owner_exec);
        const std::string ro = dir.file("ro/out.png");
        CHECK(errorOf([&] { penumbra::writePng8(ro, 2, 2, 1, grey); }) == ro + ": cannot create file: Permission denied");
        fs::permissions(dir.path / "ro", fs::perms::owner_all);
        CHECK(fs::is_empty(dir.path / "ro"));
    }
    CHECK(dir.count() == 1);  // just "plain"
}

TEST_CASE("writePng8 output reads back with stbi_load", "[io]") {
    ScratchDir dir;
    for (int channels = 1; channels <= 4; ++channels) {
        const int w = 5, h = 3;
        std::vector<uint8_t> px(static_cast<size_t>(w * h * channels));
        for (size_t i = 0; i < px.size(); ++i) px[i] = static_cast<uint8_t>(i * 37 + 11);
        const std::string path = dir.file("img" + std::to_string(channels) + ".png");
        penumbra::writePng8(path, w, h, channels, px);

        int rw = 0, rh = 0, rc = 0;
        unsigned char* loaded = stbi_load(path.c_str(), &rw, &rh, &rc, 0);
        REQUIRE(loaded != nullptr);
        CHECK(rw == w);
        CHECK(rh == h);
        CHECK(rc == channels);
        CHECK(std::vector<uint8_t>(loaded, loaded + px.size()) == px);
        stbi_image_free(loaded);
    }
    CHECK(dir.count() == 4);

    const std::string path = dir.file("wrong.png");
    CHECK(errorOf([&] { penumbra::writePng8(path, 2, 2, 3, std::vector<uint8_t>(11)); }) ==
          path + ": PNG 2x2x3 needs 12 bytes but 11 were given");
    CHECK(errorOf([&] { penumbra::writePng8(path, 2, 2, 5, std::vector<uint8_t>(20)); }) ==
          path + ": a PNG has 1 to 4 channels, not 5");
    CHECK_FALSE(fs::exists(path));
}

TEST_CASE("readExr reports unreadable files naming the path", "[io]") {
    ScratchDir dir;
    const std::string missing = dir.file("missing.exr");
    std::string msg = errorOf([&] { penumbra::readExr(missing); });
    CHECK(msg.rfind(missing + ": cannot read EXR: ", 0) == 0);
    const std::string garbage = dir.file("garbage.exr");
    { std::ofstream(garbage) << "definitely not an OpenEXR file, just some text"; }
    msg = errorOf([&] { penumbra::readExr(garbage); });
    CHECK(msg.rfind(garbage + ": cannot read EXR: ", 0) == 0);
}

TEST_CASE("encodeSrgb follows the sRGB transfer function", "[io]") {
    using penumbra::encodeSrgb;
    CHECK(encodeSrgb(0.0f) == 0);
    CHECK(encodeSrgb(1.0f) == 255);
    CHECK(encodeSrgb(-0.5f) == 0);
    CHECK(encodeSrgb(7.0f) == 255);
    CHECK(encodeSrgb(std::numeric_limits<float>::quiet_NaN()) == 0);
    CHECK(encodeSrgb(std::numeric_limits<float>::infinity()) == 255);
    CHECK(encodeSrgb(0.5f) == 188);    // 1.055 * 0.5^(1/2.4) - 0.055 = 0.7354
    CHECK(encodeSrgb(0.18f) == 118);   // middle grey: 0.4614
    CHECK(encodeSrgb(0.002f) == 7);    // linear segment: 12.92 * 0.002 * 255 = 6.59, + 0.5 rounds to 7
    CHECK(encodeSrgb(0.2158605f) == 128);  // sRGB 0.50196 = 128/255
    uint8_t previous = 0;
    for (int i = 0; i <= 4096; ++i) {
        uint8_t v = encodeSrgb(static_cast<float>(i) / 4096.0f);
        CHECK(v >= previous);
        previous = v;
    }
}
