#pragma once
// Fixtures shared by the tests: scratch directories, error capture, whole-file reads.

#include "stream/Error.h"

#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

namespace penumbra::test {

/// A file of the shared test data (../shared/data beside the project), e.g. "meshes/spot.obj".
inline std::string sharedData(const std::string& rel) { return std::string(PENUMBRA_SOURCE_DIR) + "/../shared/data/" + rel; }

/// A fresh directory under the system temp dir (mkdtemp), removed with everything in it.
struct ScratchDir {
    std::filesystem::path path;
    explicit ScratchDir(const std::string& tag = "test") {
        std::string pattern = (std::filesystem::temp_directory_path() / ("penumbra-" + tag + "-XXXXXX")).string();
        REQUIRE(::mkdtemp(pattern.data()) != nullptr);
        path = pattern;
    }
    ~ScratchDir() {
        std::error_code ec;
        std::filesystem::permissions(path, std::filesystem::perms::owner_all, std::filesystem::perm_options::add, ec);
        std::filesystem::remove_all(path, ec);
    }
    ScratchDir(const ScratchDir&) = delete;
    ScratchDir& operator=(const ScratchDir&) = delete;

    std::string file(const std::string& name) const { return (path / name).string(); }
    std::string operator/(const std::string& name) const { return file(name); }
    std::vector<std::string> entries() const {
        std::vector<std::string> names;
        for (const auto& e : std::filesystem::directory_iterator(path)) names.push_back(e.path().filename().string());
        std::sort(names.begin(), names.end());
        return names;
    }
    size_t count() const { return entries().size(); }
};

/// The message of the InputError @p action throws, or a marker when it throws none.
inline std::string errorOf(const std::function<void()>& action) {
    try {
        action();
    } catch (const InputError& e) {
        return e.what();
    }
    return "(no InputError thrown)";
}

/// The whole file as bytes in a string (empty when it cannot be read).
inline std::string slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

}  // namespace penumbra::test
