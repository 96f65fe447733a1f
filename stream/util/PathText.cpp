#include "stream/util/PathText.h"

#include <cctype>
#include <filesystem>

namespace penumbra {

std::string lowercaseExtension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

std::string comparablePath(const std::string& path) {
    const std::filesystem::path p = std::filesystem::absolute(path).lexically_normal();
    return (p.has_filename() ? p : p.parent_path()).string();
}

}  // namespace penumbra
