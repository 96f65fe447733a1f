#include "stream/TinyGltfLoad.h"
#include "stream/util/PathText.h"

#include "stream/GltfPrecheck.h"

#include "stream/util/Error.h"
#include "stream/util/RegularFile.h"

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>

#include <sys/stat.h>

namespace penumbra {
namespace {

/// The glTF image callback: geometry needs no pixels, so images are neither decoded nor checked.
bool ignoreImage(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int,
                 void*) {
    return true;
}

bool isImageFile(const std::string& path) {
    std::string ext = lowercaseExtension(path);
    for (const char* image : {".png", ".jpg", ".jpeg", ".webp", ".ktx", ".ktx2", ".basis", ".dds", ".bmp", ".tga"})
        if (ext == image) return true;
    return false;
}

// File-system callbacks for tinygltf, replacing its defaults for two reasons. Its default
// ExpandFilePath runs URIs through wordexp(3), shell word expansion ($VARS, ~ and, depending on
// how the library was built, $(command) substitution), which has no business touching names
// taken from a downloaded scene; here a URI is only ever a file name. And only regular files are
// read, so a URI naming /dev/zero or a FIFO cannot hang the load. Images are reported as
// unreadable (tinygltf then only warns) so that gigabytes of textures are never read just to
// be ignored.
bool regularFileExists(const std::string& path, void*) {
    std::error_code error;
    return std::filesystem::is_regular_file(path, error);
}

std::string pathAsIs(const std::string& path, void*) { return path; }

std::vector<unsigned char> readWholeFile(const std::string& path);

bool readRegularFile(std::vector<unsigned char>* out, std::string* err, const std::string& path, void*) {
    if (!regularFileExists(path, nullptr) || isImageFile(path)) {
        if (err) *err = "not read (not a regular file, or an image)";
        return false;
    }
    try {
        *out = readWholeFile(path);
    } catch (const InputError& e) {
        if (err) *err = e.what();
        return false;
    }
    return true;
}

bool refuseWrite(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
    if (err) *err = "penumbra does not write files while loading glTF";
    return false;
}

/// Reads a regular file whole; anything else (a device, a FIFO) could never end.
std::vector<unsigned char> readWholeFile(const std::string& path) {
    RegularFile file(path);
    // tinygltf takes lengths as unsigned int.
    if (file.size() > std::numeric_limits<unsigned int>::max())
        fail(path, "file is larger than 4 GiB, which tinygltf cannot address");
    std::vector<unsigned char> bytes(size_t(file.size()));
    file.read(bytes.data(), bytes.size(), 0);
    return bytes;
}

uint32_t readU32(const unsigned char* p) {
    uint32_t v;
    std::memcpy(&v, p, 4);
    return v;
}

/// @brief Checks the GLB container (header and the JSON and BIN chunk headers) so that
/// tinygltf, which trusts some of those lengths, only ever sees a consistent file.
/// @return the byte length the GLB header declares.
size_t checkGlbContainer(const std::string& path, const std::vector<unsigned char>& bytes) {
    if (bytes.size() < 20) fail(path, "truncated GLB header (expected at least 20 bytes, found {})", bytes.size());
    if (uint32_t version = readU32(&bytes[4]); version != 2) fail(path, "unsupported GLB version {}", version);
    uint64_t length = readU32(&bytes[8]);
    if (length > bytes.size()) fail(path, "truncated (GLB header declares {} bytes, file has {})", length, bytes.size());
    uint64_t jsonLength = readU32(&bytes[12]);
    if (readU32(&bytes[16]) != 0x4E4F534Au) fail(path, "first GLB chunk is not JSON");
    uint64_t binStart = 20 + jsonLength;
    if (binStart > length) fail(path, "GLB JSON chunk ({} bytes) runs past the end of the file", jsonLength);
    if (binStart < length) {
        if (binStart + 8 > length) fail(path, "truncated GLB chunk header after the JSON chunk");
        uint64_t binLength = readU32(&bytes[binStart]);
        if (binStart + 8 + binLength > length)
            fail(path, "GLB BIN chunk ({} bytes) runs past the end of the file", binLength);
        if (readU32(&bytes[binStart + 4]) != 0x004E4942u) fail(path, "second GLB chunk is not BIN");
    }
    return static_cast<size_t>(length);
}

}  // namespace

void loadTinyGltf(const std::string& path, tinygltf::Model& model) {
    std::vector<unsigned char> bytes = readWholeFile(path);
    checkGltfBeforeParsing(path, bytes);
    if (bytes.size() > std::numeric_limits<unsigned int>::max())  // grew while being read
        fail(path, "file is larger than 4 GiB, which tinygltf cannot address");
    // Built in one expression: assigning "." to a string here trips GCC 12's -Wrestrict false
    // positive (GCC bug 105329).
    const std::filesystem::path parent = std::filesystem::path(path).parent_path();
    const std::string baseDir = parent.empty() ? std::string(".") : parent.string();

    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(&ignoreImage, nullptr);
    loader.SetFsCallbacks({&regularFileExists, &pathAsIs, &readRegularFile, &refuseWrite, nullptr});
    std::string error, warning;
    bool loaded = false;
    try {
        if (bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0) {
            size_t length = checkGlbContainer(path, bytes);
            loaded = loader.LoadBinaryFromMemory(&model, &error, &warning, bytes.data(),
                                                 static_cast<unsigned int>(length), baseDir);
        } else {
            loaded = loader.LoadASCIIFromString(&model, &error, &warning, reinterpret_cast<const char*>(bytes.data()),
                                                static_cast<unsigned int>(bytes.size()), baseDir);
        }
    } catch (const std::exception& e) {  // tinygltf's JSON layer may throw on hostile input
        fail(path, "{}", e.what());
    }
    if (!loaded) {
        std::string firstLine = error.substr(0, error.find('\n'));
        fail(path, "{}", firstLine.empty() ? std::string("tinygltf could not load the file") : firstLine);
    }
}

}  // namespace penumbra
