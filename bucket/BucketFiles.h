#pragma once
/// @file BucketFiles.h
/// @brief Area buckets on disk: the out-of-core form of the coarse blocker sort
/// (Laine & Aila 2005, Section 3.3).
///
/// BucketWriter streams triangles into one temporary file per (area range, opaque/alpha-matte)
/// pair through small bounded buffers; finish() turns it into a BucketSet, which owns the files;
/// BucketReplaySource plays a set back as a TriangleSource, largest areas first, opaque before
/// alpha-matte, as many times as a tiled bake needs.
///
/// Layout. Each writer makes a private directory `<tmp>/penumbra-buckets-<pid>-<n>` (mode
/// 0700). A bucket file holds raw 40-byte Triangle records in stream order, nothing else; the
/// writer keeps the counts. With BucketOptions::keep the files are named
/// `opaque-NN.tri` / `alpha-NN.tri` (NN = bucket index, 00 = largest areas) next to a
/// `manifest.tsv`; without it they are anonymous.
///
/// Cleanup. Without keep, every file is created unnamed (O_TMPFILE, or created and unlinked at
/// once where the file system lacks O_TMPFILE) and the directory is removed as soon as the
/// files exist. The data lives only as long as the open descriptors, so the kernel reclaims it
/// however the process ends: normal exit, exception, SIGINT/SIGTERM, and also SIGKILL, the OOM
/// killer or a crash, which no handler sees. The only named objects ever on disk are the
/// directory and, in the fallback, one file at a time, each for microseconds; the fallback's
/// file is registered with the temp-file registry (TempRegistry.h) for that window; the
/// environment variable PENUMBRA_NO_TMPFILE=1 forces the fallback (AtomicFile.h), for its tests. With keep,
/// the named files are registered until finish() succeeds, so SIGINT/SIGTERM during the bucket
/// pass still removes them (the registry unlinks files only, so the empty directory remains).
///
/// Errors. A failed write (ENOSPC, EFBIG under a file-size limit, EIO) removes every file and
/// the directory, then throws InputError
/// `DIR: cannot write bucket 7: No space left on device (needed 409600 more bytes)`,
/// where the byte count covers everything still to be written when the triangle count is
/// known up front, and is a lower bound ("needed at least") when it is not.

#include "bucket/BucketOptions.h"
#include "bucket/BucketRanges.h"
#include "stream/TriangleSource.h"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

/// @brief One bucket file of a finished set.
struct BucketInfo {
    size_t range = 0;         ///< index in BucketRanges, 0 = largest areas
    bool alphaMatte = false;  ///< holds kTriangleAlphaMatte triangles
    AreaRange areas;          ///< every triangle's area() lies in this range
    uint64_t triangles = 0;
    uint64_t bytes = 0;       ///< file size
    std::string path;         ///< the file's name when kept; empty for an anonymous file
};

/// @brief A complete set of bucket files, ready to replay. Owns the open files: destroying the
/// set releases them (and, unless kept, the disk space). Move-only.
class BucketSet {
public:
    BucketSet(BucketSet&& other) noexcept;
    BucketSet& operator=(BucketSet&& other) noexcept;
    BucketSet(const BucketSet&) = delete;
    BucketSet& operator=(const BucketSet&) = delete;
    ~BucketSet();

    /// The private directory; it no longer exists unless kept() (names stay useful in messages).
    const std::string& directory() const { return directory_; }
    /// True when the files stay on disk after the set is destroyed.
    bool kept() const { return kept_; }
    const BucketRanges& ranges() const { return ranges_; }
    /// @brief All 2 x ranges().count() buckets in replay order: opaque from the largest range to
    /// the smallest, then alpha-matte likewise. Empty buckets are listed too.
    const std::vector<BucketInfo>& buckets() const { return buckets_; }

    uint64_t triangles() const { return opaqueTriangles_ + alphaMatteTriangles_; }
    uint64_t opaqueTriangles() const { return opaqueTriangles_; }
    uint64_t alphaMatteTriangles() const { return alphaMatteTriangles_; }
    /// Bytes written to the bucket files (= their total size).
    uint64_t bytes() const { return bytes_; }

    /// @brief The open descriptor of bucket @p index (in buckets() order), for reading with
    /// pread(2); shared by every replay, so it must not be seeked or closed.
    int fileDescriptor(size_t index) const { return fds_[index]; }

private:
    friend class BucketWriter;
    BucketSet() = default;
    void close() noexcept;

    std::string directory_;
    bool kept_ = false;
    BucketRanges ranges_;
    std::vector<BucketInfo> buckets_;
    std::vector<int> fds_;
    uint64_t opaqueTriangles_ = 0;
    uint64_t alphaMatteTriangles_ = 0;
    uint64_t bytes_ = 0;
};

/// @brief Streams triangles into bucket files. Heap use is bounded by
/// BucketOptions::writeMemoryBytes(), whatever the triangle count. Not thread safe.
class BucketWriter {
public:
    /// @brief Creates the private directory and every bucket file.
    /// @param ranges the area ranges (see AreaHistogram for choosing them).
    /// @param options directory, keep, buffer size; validated here.
    /// @param expectedTriangles the source's sizeHint(), if any; only used to say how many bytes
    ///        a failed write still needed.
    /// @throw InputError naming the temp directory when it cannot be created or the files cannot
    ///        be opened (missing or read-only directory, too many buckets for `ulimit -n`).
    BucketWriter(BucketRanges ranges, const BucketOptions& options,
                 std::optional<uint64_t> expectedTriangles = std::nullopt);
    /// Removes every file and the directory unless finish() succeeded.
    ~BucketWriter();
    BucketWriter(const BucketWriter&) = delete;
    BucketWriter& operator=(const BucketWriter&) = delete;

    /// @brief Appends @p triangles to their buckets, by area() and the alpha-matte flag.
    /// @throw InputError "DIR: cannot write bucket N: REASON (needed M more bytes)" when the
    ///        disk is full or a file-size limit is hit; everything is removed first, and the
    ///        writer then only accepts destruction.
    void write(std::span<const Triangle> triangles);
    /// @brief Appends one triangle.
    void write(const Triangle& triangle) { write(std::span<const Triangle>(&triangle, 1)); }
    /// @brief write() with each triangle's bucket already found: @p buckets[i] is
    /// bucketOf(@p triangles[i]). The look-up is the pass's only arithmetic per triangle, so a
    /// caller with more threads than writers finds it in parallel (bucket/BucketPlan.cpp).
    /// @pre @p buckets.size() == @p triangles.size()
    /// @throw InputError as write() does.
    void write(std::span<const Triangle> triangles, std::span<const uint32_t> buckets);
    /// @brief The bucket @p t goes to: its area's range, after the opaque ones when it is an
    /// alpha matte. Thread safe (reads only the ranges).
    uint32_t bucketOf(const Triangle& t) const;

    /// @brief Flushes every buffer, frees them, writes the manifest when keeping, and hands the
    /// files over. The writer is empty afterwards.
    /// @throw InputError as write() does.
    BucketSet finish();

    /// The private directory (see BucketSet::directory()).
    const std::string& directory() const { return directory_; }
    /// Triangles accepted so far.
    uint64_t triangles() const { return accepted_; }
    /// Bytes handed to write(2) successfully so far.
    uint64_t bytesWritten() const { return bytesWritten_; }
    /// Heap bytes currently held by write buffers; never above options.writeMemoryBytes().
    uint64_t bufferBytes() const { return allocatedBufferBytes_; }

private:
    struct Slot;

    void open();
    void flush(Slot& slot, size_t index);
    [[noreturn]] void failWrite(size_t index, int err, uint64_t unwritten);
    void discard() noexcept;
    std::string slotLabel(size_t index) const;

    BucketRanges ranges_;
    BucketOptions options_;
    std::optional<uint64_t> expected_;
    std::string directory_;
    bool directoryExists_ = false;
    std::vector<Slot> slots_;
    size_t bufferCapacity_ = 0;  // writeBufferBytes rounded down to whole records
    uint64_t accepted_ = 0;
    uint64_t bytesWritten_ = 0;
    uint64_t allocatedBufferBytes_ = 0;
    bool finished_ = false;
    bool failed_ = false;
};

/// @brief Plays a BucketSet back: opaque buckets from the largest area range to the smallest,
/// then the alpha-matte ones likewise; within a bucket, in the order the triangles were written.
///
/// Reads with pread(2) at its own offsets, so several replays of one set may run at once (one
/// per thread) and a rewind costs nothing. Requests of at least the read buffer's size go
/// straight into the caller's span; smaller ones are served from the bounded buffer.
class BucketReplaySource final : public TriangleSource {
public:
    /// @param set the buckets; shared so that replays may outlive the code that wrote them.
    /// @param readBufferBytes bound on the internal buffer (rounded down to whole records).
    explicit BucketReplaySource(std::shared_ptr<const BucketSet> set, size_t readBufferBytes = 256 * 1024);

    /// @throw InputError naming the bucket directory when a file is shorter than written or
    ///        cannot be read.
    size_t read(std::span<Triangle> out) override;
    void rewind() override;
    std::string name() const override { return set_->directory(); }
    std::optional<uint64_t> sizeHint() const override { return set_->triangles(); }
    /// The opaque triangles, then the alpha-matte ones (which cost more each: alpha tests).
    std::vector<uint64_t> costRuns() const override { return {set_->opaqueTriangles(), set_->alphaMatteTriangles()}; }

    const BucketSet& buckets() const { return *set_; }
    /// Index (in BucketSet::buckets() order) of the bucket the next triangle comes from;
    /// buckets().buckets().size() at the end.
    size_t currentBucket() const { return bucket_; }
    /// Bytes read from bucket files since construction, over every pass.
    uint64_t bytesRead() const { return bytesRead_; }
    /// Completed rewinds + 1: how many times the replay has been (or is being) played.
    uint64_t passes() const { return passes_; }
    /// Seconds spent inside pread(2) since construction.
    double readSeconds() const { return readSeconds_; }

private:
    size_t readFile(void* dst, size_t bytes);
    void skipEmptyBuckets();

    std::shared_ptr<const BucketSet> set_;
    std::vector<uint8_t> buffer_;
    size_t bufferBegin_ = 0, bufferEnd_ = 0;
    size_t bucket_ = 0;
    uint64_t offset_ = 0;  // in the current bucket's file
    uint64_t bytesRead_ = 0;
    uint64_t passes_ = 1;
    double readSeconds_ = 0;
};

}  // namespace penumbra
