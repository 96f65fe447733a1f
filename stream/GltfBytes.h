#pragma once
/// @file GltfBytes.h
/// @brief Reading glTF buffer bytes window by window, never a whole buffer or file.
///
/// Memory contract, per reader (one per open glTF source):
/// - raw bytes: a cache of kGltfCacheBlocks blocks of kGltfBlockBytes (32 x 64 KiB = 2 MiB),
///   least recently used first out, filled with pread(2) from the .glb's BIN chunk or the
///   external .bin file. Nothing is mapped, so the address space a bake needs does not grow with
///   the file. Indexed primitives hit the cache as exporters lay meshes out (indices in order,
///   vertices near each other), and stay bounded however the indices jump.
/// - EXT_meshopt_compression views cannot be decoded in parts, so a compressed view is decoded
///   whole when first read, and decoded views are kept up to the decoder budget given at
///   construction (the two most recently used are always kept: a primitive's positions and
///   indices). The compressed input is read straight from the file into a buffer freed after
///   decoding. gltfDecodedViewBytes() says what one view needs, for memory plans.
/// - `data:` URI buffers are already resident in the document (GltfDocument.h).
///
/// Not thread safe: one reader per thread (the blocker stream runs on the read-ahead thread).

#include "stream/GltfDocument.h"

#include <cstdint>
#include <list>
#include <memory>
#include <vector>

namespace penumbra {

inline constexpr uint64_t kGltfBlockBytes = 64 * 1024;
inline constexpr size_t kGltfCacheBlocks = 32;

/// @brief Bytes a decoded view needs resident: its decoded size for a meshopt view, else 0.
uint64_t gltfDecodedViewBytes(const GltfDocument& doc, int view);

class GltfBytes {
public:
    /// @param doc the document whose buffers are read; must outlive the reader.
    /// @param decodedBudget bytes of decoded meshopt views kept at once (see above).
    GltfBytes(const GltfDocument& doc, uint64_t decodedBudget);
    ~GltfBytes();
    GltfBytes(const GltfBytes&) = delete;
    GltfBytes& operator=(const GltfBytes&) = delete;

    /// @brief Bytes [offset, offset + size) of buffer view @p view, size <= 256; the pointer is
    /// valid until the next call. The range must lie inside the view (GltfDocument checked every
    /// accessor).
    /// @throw InputError naming the file on a read error or a meshopt view that does not decode.
    const uint8_t* at(int view, uint64_t offset, uint32_t size);

    /// @brief Copies @p size bytes at @p offset of buffer @p buffer (raw, undecoded) to @p out.
    void copy(int buffer, uint64_t offset, uint64_t size, uint8_t* out);

    /// Heap bytes held now (blocks and decoded views), and the most ever held.
    uint64_t bytesHeld() const { return blockBytes_ + decodedBytes_; }
    uint64_t peakBytesHeld() const { return peak_; }

    /// Releases every block and decoded view (between passes).
    void clear();

private:
    struct Block {
        int buffer = -1;
        uint64_t index = 0;
        uint64_t lastUse = 0;
        size_t size = 0;
        std::unique_ptr<uint8_t[]> data;
    };
    struct Decoded {
        int view = -1;
        std::vector<uint8_t> bytes;
    };

    const uint8_t* raw(int buffer, uint64_t offset, uint32_t size);
    Block& block(int buffer, uint64_t index);
    const std::vector<uint8_t>& decoded(int view);
    int descriptor(int buffer);
    void note();

    const GltfDocument& doc_;
    uint64_t decodedBudget_;
    std::vector<Block> blocks_;
    size_t mru_[2] = {0, 0};
    uint64_t clock_ = 0;
    std::list<Decoded> decoded_;  // most recent first
    std::vector<int> fds_;        // per buffer, -1 until opened
    uint64_t blockBytes_ = 0, decodedBytes_ = 0, peak_ = 0;
    uint8_t scratch_[256];
};

}  // namespace penumbra
