#pragma once
/// @file StreamTestFiles.h
/// @brief Small helpers shared by the stream-stage tests: whole-file byte I/O and bit-exact
/// triangle comparison (scratch directories and the shared data are in TestSupport.h).

#include "TestSupport.h"
#include "stream/Triangle.h"

#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <string_view>
#include <vector>

namespace penumbra::test {

inline void writeBytes(const std::string& path, const void* data, size_t size) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
}

inline void writeText(const std::string& path, std::string_view text) { writeBytes(path, text.data(), text.size()); }

inline void writeBytes(const std::string& path, const std::vector<uint8_t>& bytes) {
    writeBytes(path, bytes.data(), bytes.size());
}

inline std::vector<uint8_t> readBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Same coordinates to the bit (so -0 differs from +0) and same flags.
inline bool sameBits(const Triangle& a, const Triangle& b) { return std::memcmp(&a, &b, sizeof(Triangle)) == 0; }

inline bool sameBits(const std::vector<Triangle>& a, const std::vector<Triangle>& b) {
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(Triangle)) == 0);
}

inline Triangle tri(glm::vec3 a, glm::vec3 b, glm::vec3 c, uint32_t flags = 0) {
    Triangle t;
    t.v = {a, b, c};
    t.flags = flags;
    return t;
}

}  // namespace penumbra::test
