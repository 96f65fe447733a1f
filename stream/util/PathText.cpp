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
    // Symbolic links resolved as far as the path exists (a folder reached through a link is the
    // folder), then "." and ".." folded: o2/a.exr, ./o2/a.exr and L/a.exr with L -> o2 compare equal.
    std::error_code ec;
    std::filesystem::path p = std::filesystem::weakly_canonical(std::filesystem::absolute(path), ec);
    if (ec) p = std::filesystem::absolute(path);
    p = p.lexically_normal();
    return (p.has_filename() ? p : p.parent_path()).string();
}

}  // namespace penumbra
