#pragma once
/// @file PtriFormat.h
/// @brief penumbra's own binary triangle stream, `.ptri`: a converted scene that reads back at
/// disk speed, with every byte covered by a checksum.
///
/// Buffer contract (all fields little-endian, no padding; offsets in bytes):
///
///     header, 48 bytes
///       0  char[4]    magic "PTRI"
///       4  uint32     version, 1
///       8  uint64     triangle count N
///      16  float32[3] bounds min (0,0,0 when N = 0)
///      28  float32[3] bounds max (0,0,0 when N = 0)
///      40  uint32     chunk size C, triangles per chunk, 1 <= C <= kPtriMaxChunk
///      44  uint32     FNV-1a 32 of bytes 0..43
///     then ceil(N / C) chunks, chunk k being
///       0  uint32     triangle count n_k: C for every chunk but the last, which holds the rest
///       4  uint32     FNV-1a 32 of the 4 count bytes followed by the payload
///       8  payload    n_k records of 40 bytes: float32 v0[3], v1[3], v2[3], uint32 flags
///                     (exactly the in-memory layout of struct Triangle)
///     and nothing after the last chunk.
///
/// Because every chunk but the last is full, the file size follows from the header alone:
/// 48 + ceil(N / C) * 8 + N * 40. Readers check it at open, so truncation is reported before
/// any triangle is produced, and chunk k starts at a computable offset. FNV-1a detects every
/// single-byte change, and covering the count field means a damaged count cannot make a
/// reader skip or misalign payload. All coordinates are finite.

#include "stream/TriangleSource.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

class AtomicFile;

inline constexpr char kPtriMagic[4] = {'P', 'T', 'R', 'I'};
inline constexpr uint32_t kPtriVersion = 1;
inline constexpr uint32_t kPtriDefaultChunk = 4096;
/// Upper bound on the chunk size, so that a hostile header cannot make a reader allocate more
/// than 40 MiB for one chunk.
inline constexpr uint32_t kPtriMaxChunk = 1u << 20;
inline constexpr size_t kPtriHeaderBytes = 48;
inline constexpr size_t kPtriChunkHeaderBytes = 8;
inline constexpr size_t kPtriTriangleBytes = 40;

/// FNV-1a 32-bit offset basis: the hash of no bytes, and the seed of a fresh hash.
inline constexpr uint32_t kFnv1aBasis = 2166136261u;

/// @brief FNV-1a 32 of @p size bytes, continuing from @p hash (chain calls to hash pieces).
uint32_t fnv1a32(const void* data, size_t size, uint32_t hash = kFnv1aBasis);

/// What a .ptri header says.
struct PtriInfo {
    uint64_t triangles = 0;
    glm::vec3 lo{0}, hi{0};
    uint32_t chunkSize = kPtriDefaultChunk;

    /// Number of chunks in the file.
    uint64_t chunkCount() const { return (triangles + chunkSize - 1) / chunkSize; }
    /// Triangles in chunk @p k (all are full but the last).
    uint32_t chunkTriangles(uint64_t k) const;
    /// The size a complete file with this header has.
    uint64_t fileBytes() const;
};

/// @brief Writes a .ptri file atomically: nothing appears at the destination until finish().
///
/// Triangles are buffered into chunks of chunkSize and written as each chunk fills; the header
/// (count and bounds) is patched in by finish(), which then renames the temporary into place.
/// Destroying a writer without finish() (an exception, a cancelled conversion) deletes the
/// temporary and leaves any existing file at the destination untouched.
class PtriWriter {
public:
    /// @param path destination; its directory must be writable (the temporary lives there).
    /// @param chunkSize triangles per chunk, 1..kPtriMaxChunk.
    /// @throw InputError naming @p path when the temporary cannot be created.
    explicit PtriWriter(std::string path, uint32_t chunkSize = kPtriDefaultChunk);
    ~PtriWriter();
    PtriWriter(const PtriWriter&) = delete;
    PtriWriter& operator=(const PtriWriter&) = delete;

    /// @brief Appends triangles.
    /// @throw InputError naming the path for a non-finite triangle or a failed write
    ///        (with how many bytes could not be written).
    void write(std::span<const Triangle> triangles);

    /// @brief Writes the last chunk and the final header, syncs, and renames into place.
    /// @throw InputError naming the path when any of that fails; the temporary is removed.
    void finish();

    /// Triangles accepted so far.
    uint64_t triangleCount() const { return count_; }

private:
    void flushChunk();
    void writeBytes(const void* data, size_t size, int64_t offset);

    std::string path_;
    uint32_t chunkSize_;
    std::unique_ptr<AtomicFile> file_;  // owns the temporary's name, cleanup and final rename
    int fd_ = -1;                       // file_'s descriptor: the header needs pwrite
    std::vector<Triangle> chunk_;
    uint64_t count_ = 0;
    glm::vec3 lo_{0}, hi_{0};
    bool finished_ = false;
};

/// @brief Reads and verifies a .ptri header: magic, version, header checksum, chunk size, and
/// that the file size is exactly what the header implies.
/// @throw InputError naming @p path, e.g. `scene.ptri: truncated in chunk 7 (expected 163848
///        bytes, found 1200)` or `scene.ptri: header checksum mismatch`.
PtriInfo readPtriHeader(const std::string& path);

/// @brief Opens a .ptri file as a streaming source; sizeHint() is the header's count.
///
/// The header and file size are verified here (see readPtriHeader); each chunk's count and
/// checksum are verified as read() reaches it, so a damaged chunk fails that read() with e.g.
/// `scene.ptri: checksum mismatch in chunk 3`. Only one chunk is held in memory, and the file
/// is open only while a pass is under way (from the first read() to the last chunk).
/// @throw InputError as readPtriHeader.
TriangleSourcePtr openPtri(const std::string& path);

}  // namespace penumbra
