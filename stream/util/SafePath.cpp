#include "stream/util/SafePath.h"

#include "stream/util/Error.h"

#include <atomic>

namespace fs = std::filesystem;

namespace penumbra {
namespace {

std::atomic<bool> g_allowOutside{false};

unsigned char hexValue(unsigned char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return 0;  // as tinygltf: a non-hex digit counts as 0
}

/// @p path without a trailing separator, absolute and lexically normal.
fs::path normalAbsolute(const fs::path& path) {
    fs::path p = fs::absolute(path.empty() ? fs::path(".") : path).lexically_normal();
    if (!p.has_filename() && p != p.root_path()) p = p.parent_path();
    return p;
}

/// The longest existing prefix of @p path with its symbolic links resolved, followed by the rest.
fs::path resolvedLinks(const fs::path& path) {
    std::error_code ec;
    fs::path canonical = fs::weakly_canonical(path, ec);
    return ec ? path : canonical;
}

}  // namespace

bool isInside(const fs::path& inner, const fs::path& outer) {
    const fs::path rel = inner.lexically_relative(outer);
    return !rel.empty() && *rel.begin() != "..";
}

void setOutsidePathsAllowed(bool allowed) { g_allowOutside.store(allowed); }

bool outsidePathsAllowed() { return g_allowOutside.load(); }

std::string percentDecode(std::string_view uri) {
    std::string out;
    out.reserve(uri.size());
    for (size_t i = 0; i < uri.size(); ++i) {
        if (uri[i] == '+') {
            out += ' ';
        } else if (uri[i] == '%' && uri.size() > i + 2) {
            out += char((hexValue(uri[i + 1]) << 4) | hexValue(uri[i + 2]));
            i += 2;
        } else {
            out += uri[i];
        }
    }
    return out;
}

std::string containedPath(const fs::path& baseDir, const std::string& name, const std::string& where, const char* what) {
    if (name.find('\0') != std::string::npos) fail(where, "the path contains a NUL byte");
    const fs::path named(name);
    const std::string resolved = (named.is_absolute() ? named : baseDir / named).lexically_normal().string();
    if (outsidePathsAllowed()) return resolved;
    const fs::path base = normalAbsolute(baseDir), target = normalAbsolute(resolved);
    if (!isInside(target, base))
        fail(where, "\"{}\" leaves {} {} (--allow-outside-uris allows it)", name, what, base.string());
    const fs::path realBase = resolvedLinks(base), realTarget = resolvedLinks(target);
    if (!isInside(realTarget, realBase))
        fail(where, "\"{}\" leads out of {} {} through a symbolic link, to {} (--allow-outside-uris allows it)", name,
             what, base.string(), realTarget.string());
    return resolved;
}

}  // namespace penumbra
