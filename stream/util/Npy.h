#pragma once
/// @file Npy.h
/// @brief NumPy .npy arrays: receiver point lists in, per-point results out.
///
/// Format reference: numpy/lib/format.py ("NEP 1"). A file is the magic "\x93NUMPY", a
/// version byte pair, a little-endian header length (2 bytes in v1.0, 4 bytes in v2.0/3.0),
/// a Python dict literal such as `{'descr': '<f4', 'fortran_order': False, 'shape': (10, 3), }`
/// padded with spaces and a final '\n', then the raw C-ordered data.
///
/// Only simple little-endian numeric dtypes are supported; that covers everything a point
/// list or a result array can reasonably be, and keeps the reader small enough to audit
/// against hostile input.

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace penumbra {

/// @brief An array loaded from, or about to be written to, a .npy file.
struct NpyArray {
    /// NumPy type string, normalised: "<f4", "<f8", "<i4", "<u8", "|u1", "|b1", ...
    /// (native '=' is stored as '<', one-byte types always as '|').
    std::string dtype;
    std::vector<uint64_t> shape;  ///< empty for a 0-d (scalar) array
    std::vector<uint8_t> data;    ///< C order, little endian, elementCount() * itemSize() bytes

    /// Product of shape (1 for a scalar).
    size_t elementCount() const;
    /// Bytes per element of dtype.
    size_t itemSize() const;
};

/// @brief The validated header of a .npy file.
struct NpyHeader {
    std::string dtype;            ///< normalised, as in NpyArray
    std::vector<uint64_t> shape;
    uint64_t dataBytes = 0;       ///< checked against the shape
};

/// @brief A .npy file opened for reading its rows a block at a time, for arrays too large to
/// hold whole (dumps of millions of receivers). The header gets readNpy()'s checks on opening.
class NpyRowReader {
public:
    /// @throw InputError as readNpy() does for the header.
    explicit NpyRowReader(const std::string& path);
    const NpyHeader& header() const { return header_; }
    /// @brief Reads the next @p rows rows (a row is everything below the first axis) into
    /// @p out, resized to hold them exactly.
    /// @throw InputError naming the file when it ends early or a read fails.
    template <class T>
    void next(uint64_t rows, std::vector<T>& out) {
        out.resize(size_t(rows * rowBytes_ / sizeof(T)));
        read(out.data(), size_t(rows * rowBytes_));
    }

private:
    void read(void* dst, size_t bytes);
    std::string path_;
    NpyHeader header_;
    uint64_t rowBytes_ = 0;
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> file_{nullptr, &std::fclose};
};

/// @brief Reads a whole .npy file (versions 1.0, 2.0 and 3.0).
/// @param path file to read; also the prefix of every error message.
/// @throw InputError naming @p path for a missing file, bad magic, unknown version, malformed
///        header dict, unsupported (big-endian, structured, object) dtype, Fortran order, or a
///        data length that disagrees with the header, e.g.
///        "pts.npy: header says 1000x6 float32 (24000 bytes) but file has 12000 bytes of data".
NpyArray readNpy(const std::string& path);

/// @brief The array's elements as float32, converting from float64 if needed.
/// @param path used only for the error message.
/// @throw InputError when the dtype is not "<f4" or "<f8".
std::vector<float> npyAsFloat32(const NpyArray& array, const std::string& path);

/// @brief Writes a version 1.0 .npy file atomically (see AtomicFile).
/// @param dtype NumPy type string, little endian or '|' (e.g. "<f4", "<u8", "|u1").
/// @param shape dimensions, outermost first; empty for a scalar.
/// @param bytes must equal product(shape) * itemsize(dtype).
/// @throw InputError naming @p path on an unsupported dtype, a size mismatch or an I/O error.
void writeNpy(const std::string& path, std::string_view dtype, std::span<const uint64_t> shape,
              const void* data, size_t bytes);

/// @brief Convenience overload for a whole NpyArray.
void writeNpy(const std::string& path, const NpyArray& array);

/// @brief Human-readable dtype name for messages: "<f4" -> "float32", "|u1" -> "uint8".
std::string npyTypeName(std::string_view dtype);

}  // namespace penumbra
