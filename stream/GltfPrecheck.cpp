#include "stream/GltfPrecheck.h"

#include "stream/Error.h"
#include "stream/InputFile.h"
#include "stream/JsonText.h"
#include "stream/SafePath.h"

#include <nlohmann/json.hpp>

#include <sys/stat.h>

#include <cstring>
#include <filesystem>
#include <string_view>

namespace penumbra {
namespace {

/// The JSON text of a .gltf (the whole file) or a .glb (its first chunk); empty when a GLB's
/// header does not hold together (the reader says why).
std::string_view jsonText(std::span<const unsigned char> bytes) {
    const auto* chars = reinterpret_cast<const char*>(bytes.data());
    if (bytes.size() < 4 || std::memcmp(chars, "glTF", 4) != 0) return {chars, bytes.size()};
    if (bytes.size() < 20) return {};
    uint32_t length = 0;
    std::memcpy(&length, chars + 12, 4);
    if (uint64_t(length) > bytes.size() - 20) return {};
    return {chars + 20, length};
}

bool exists(const std::string& path) {
    struct stat st {};
    return ::stat(path.c_str(), &st) == 0;
}

/// Checks the "uri" of every entry of @p list ("buffers" or "images").
void checkUris(const std::string& path, const nlohmann::json& root, const char* list) {
    auto it = root.find(list);
    if (it == root.end() || !it->is_array()) return;
    const std::filesystem::path baseDir = std::filesystem::path(path).parent_path();
    for (size_t i = 0; i < it->size(); ++i) {
        const nlohmann::json& entry = (*it)[i];
        if (!entry.is_object()) continue;
        auto uri = entry.find("uri");
        if (uri == entry.end() || !uri->is_string()) continue;
        const std::string text = uri->get<std::string>();
        if (text.empty() || text.rfind("data:", 0) == 0) continue;  // embedded, no file
        const std::string where = fmt::format("{}: {}[{}].uri", path, list, i);
        const std::string decoded = percentDecode(text);
        const std::string file = containedPath(baseDir, decoded, where, "the model's directory");
        if (outsidePathsAllowed()) continue;
        if (!exists(file)) {
            // tinygltf tries the current directory when the model's has no such file.
            if (exists(decoded))
                fail(where, "\"{}\" is not in the model's directory, and the file of that name in the current "
                            "directory is not read in its place",
                     text);
            continue;  // tinygltf reports a missing buffer; a missing image is only a warning
        }
        if (std::string_view(list) == "buffers") checkInputFile(file);
    }
}

}  // namespace

void checkGltfBeforeParsing(const std::string& path, std::span<const unsigned char> bytes) {
    const std::string_view text = jsonText(bytes);
    checkJsonDepth(text, path);
    nlohmann::json root = nlohmann::json::parse(text.begin(), text.end(), nullptr, /*allow_exceptions=*/false);
    if (!root.is_object()) return;  // not JSON, or not a glTF: the reader's error
    checkUris(path, root, "buffers");
    checkUris(path, root, "images");
}

}  // namespace penumbra
