#pragma once
/// @file BucketOptions.h
/// @brief Settings of the out-of-core bucket pass (`--tmp`, `--keep-buckets`, bucket count,
/// buffer sizes), and the memory they imply.

#include "stream/Triangle.h"

#include <cstddef>
#include <cstdint>
#include <string>

namespace penumbra {

struct BucketOptions {
    /// Area ranges. Opaque and alpha-matte triangles each get this many files (2x in all).
    int buckets = 32;
    /// Parent of the private bucket directory; empty means std::filesystem::temp_directory_path()
    /// (which honours $TMPDIR).
    std::string tmpDir;
    /// Keep a complete bucket set on disk after the process ends (`--keep-buckets`), with a
    /// manifest.tsv describing it. An incomplete set (write error, signal, abandoned writer) is
    /// removed regardless: it cannot be replayed, and after a full disk the space matters more.
    bool keep = false;
    /// Write-behind buffer per bucket file, allocated on the bucket's first triangle. 64 KiB
    /// amortizes the write(2) call (~5 us) over 1600 triangles, and 64 buckets of it are 4 MiB.
    size_t writeBufferBytes = 64 * 1024;
    /// Read buffer of a replay. Chunks of at least this size are read straight into the caller's
    /// span, so for the pipeline's 4096-triangle chunks (160 KiB) it is rarely touched.
    size_t readBufferBytes = 256 * 1024;

    /// @brief Checks ranges: 1 <= buckets <= kMaxBuckets, buffers from one triangle to 64 MiB.
    /// @throw InputError "bucket options: ..." naming the bad setting.
    void validate() const;

    /// Upper bound of the bucket writer's heap use: every file's write buffer.
    uint64_t writeMemoryBytes() const { return 2 * uint64_t(buckets) * writeBufferBytes; }

    /// Most buckets allowed: each bucket costs two open file descriptors.
    static constexpr int kMaxBuckets = 1024;
};

/// Bytes one triangle takes in a bucket file: records are raw (see docs/buckets.md for why).
inline constexpr size_t kBucketRecordBytes = sizeof(Triangle);

}  // namespace penumbra
