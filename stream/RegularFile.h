#pragma once
/// @file RegularFile.h
/// @brief A read-only regular file read with pread(2): devices and FIFOs, which could never end
/// or never answer, are refused when it is opened.

#include <cstddef>
#include <cstdint>
#include <string>

namespace penumbra {

class RegularFile {
public:
    /// @throw InputError "PATH: cannot open: REASON" or "PATH: not a regular file".
    explicit RegularFile(const std::string& path);
    ~RegularFile();
    RegularFile(const RegularFile&) = delete;
    RegularFile& operator=(const RegularFile&) = delete;

    uint64_t size() const { return size_; }
    /// @brief Reads exactly @p bytes at @p offset. @throw InputError naming the file on a read
    /// error or when the file ends first (it shrank while being read).
    void read(void* out, size_t bytes, uint64_t offset) const;

private:
    std::string path_;
    int fd_ = -1;
    uint64_t size_ = 0;
};

}  // namespace penumbra
