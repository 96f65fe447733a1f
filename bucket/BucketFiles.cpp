#include "bucket/BucketFiles.h"

#include "stream/util/AnonymousFile.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/Progress.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>

namespace penumbra {

namespace {


/// Writes all of @p bytes; returns 0 or the errno of the failure, with @p written telling how far
/// it got (a file-size limit typically allows a short write first and fails the next call).
int writeAll(int fd, const uint8_t* data, size_t bytes, size_t& written) {
    written = 0;
    while (written < bytes) {
        ssize_t n = ::write(fd, data + written, bytes - written);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) return errno;
        if (n == 0) return EIO;  // a regular file never accepts nothing without saying why
        written += static_cast<size_t>(n);
    }
    return 0;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// BucketSet

BucketSet::BucketSet(BucketSet&& other) noexcept { *this = std::move(other); }

BucketSet& BucketSet::operator=(BucketSet&& other) noexcept {
    if (this == &other) return *this;
    close();
    directory_ = std::move(other.directory_);
    kept_ = other.kept_;
    ranges_ = std::move(other.ranges_);
    buckets_ = std::move(other.buckets_);
    fds_ = std::move(other.fds_);
    other.fds_.clear();
    opaqueTriangles_ = other.opaqueTriangles_;
    alphaMatteTriangles_ = other.alphaMatteTriangles_;
    bytes_ = other.bytes_;
    return *this;
}

BucketSet::~BucketSet() { close(); }

void BucketSet::close() noexcept {
    // Unkept files are unnamed: closing the last descriptor is what frees their space.
    for (int fd : fds_)
        if (fd >= 0) ::close(fd);
    fds_.clear();
}

// ---------------------------------------------------------------------------------------------
// BucketWriter

struct BucketWriter::Slot {
    int fd = -1;
    std::string path;         // named (kept) files only
    bool registered = false;  // path is in the temp-file registry
    std::unique_ptr<uint8_t[]> buffer;
    size_t used = 0;
    uint64_t triangles = 0;
    uint64_t bytes = 0;
};

BucketWriter::BucketWriter(BucketRanges ranges, const BucketOptions& options, std::optional<uint64_t> expectedTriangles)
    : ranges_(std::move(ranges)), options_(options), expected_(expectedTriangles) {
    options_.validate();
    if (ranges_.count() > size_t(BucketOptions::kMaxBuckets))
        fail("bucket options", "{} area ranges given, at most {} are supported", ranges_.count(), BucketOptions::kMaxBuckets);
    bufferCapacity_ = options_.writeBufferBytes - options_.writeBufferBytes % kBucketRecordBytes;
    slots_.resize(2 * ranges_.count());
    try {
        open();
    } catch (...) {
        discard();
        throw;
    }
}

BucketWriter::~BucketWriter() {
    if (!finished_) discard();
}

void BucketWriter::open() {
    std::string parent = options_.tmpDir;
    if (parent.empty()) parent = systemTempDirectory();

    // pid keeps processes apart, the counter keeps several writers of one process apart, and a
    // leftover of a killed run with a recycled pid just makes us take the next number.
    static std::atomic<uint64_t> counter{0};
    for (int attempt = 0;; ++attempt) {
        directory_ = (std::filesystem::path(parent) /
                      fmt::format("penumbra-buckets-{}-{}", static_cast<long>(::getpid()), counter.fetch_add(1)))
                         .string();
        if (::mkdir(directory_.c_str(), 0700) == 0) break;
        int err = errno;
        if (err == EEXIST && attempt < 1000) continue;
        directory_.clear();
        fail(parent, "cannot create bucket directory: {}", errnoText(err));
    }
    directoryExists_ = true;

    for (size_t i = 0; i < slots_.size(); ++i) {
        Slot& slot = slots_[i];
        if (options_.keep) {
            slot.path = fmt::format("{}/{}-{:02}.tri", directory_, i < ranges_.count() ? "opaque" : "alpha",
                                    i % ranges_.count());
            // Registered before it exists, so no signal can fall between creation and registration.
            registerTempFile(slot.path);
            slot.registered = true;
            slot.fd = ::open(slot.path.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
        } else {
            slot.fd = createAnonymousFile(directory_);
        }
        if (slot.fd < 0) {
            int err = errno;
            if (err == EMFILE || err == ENFILE)
                fail(directory_, "cannot create bucket files: {} ({} buckets need {} open files; raise `ulimit -n` or use fewer buckets)",
                     errnoText(err), ranges_.count(), slots_.size());
            fail(directory_, "cannot create bucket file {}: {}", slotLabel(i), errnoText(err));
        }
    }

    // Unkept files have no names, so the directory is empty and has done its job.
    if (!options_.keep && ::rmdir(directory_.c_str()) == 0) directoryExists_ = false;
}

std::string BucketWriter::slotLabel(size_t index) const {
    size_t range = index % ranges_.count();
    return index < ranges_.count() ? fmt::format("bucket {}", range) : fmt::format("alpha-matte bucket {}", range);
}

uint32_t BucketWriter::bucketOf(const Triangle& t) const {
    const size_t index = ranges_.bucketOf(t.area());
    return uint32_t(t.flags & kTriangleAlphaMatte ? index + ranges_.count() : index);
}

void BucketWriter::write(std::span<const Triangle> triangles) {
    // In parts of 256, and at least one (empty) part, so that the checks of the write below
    // also run for an empty span.
    std::array<uint32_t, 256> buckets;
    size_t first = 0;
    do {
        const std::span<const Triangle> part = triangles.subspan(first, std::min(buckets.size(), triangles.size() - first));
        for (size_t i = 0; i < part.size(); ++i) buckets[i] = bucketOf(part[i]);
        write(part, std::span<const uint32_t>(buckets.data(), part.size()));
        first += part.size();
    } while (first < triangles.size());
}

void BucketWriter::write(std::span<const Triangle> triangles, std::span<const uint32_t> buckets) {
    if (failed_) fail(directory_, "cannot write buckets: an earlier write failed");
    if (finished_) throw std::logic_error("BucketWriter::write after finish()");
    if (buckets.size() != triangles.size()) throw std::logic_error("BucketWriter::write: one bucket per triangle");
    for (size_t i = 0; i < triangles.size(); ++i) {
        const size_t index = buckets[i];
        Slot& slot = slots_[index];
        if (!slot.buffer) {
            // Allocated on first use: a scene without foliage never pays for alpha buffers.
            slot.buffer = std::make_unique<uint8_t[]>(bufferCapacity_);
            allocatedBufferBytes_ += bufferCapacity_;
        }
        std::memcpy(slot.buffer.get() + slot.used, &triangles[i], kBucketRecordBytes);
        slot.used += kBucketRecordBytes;
        ++slot.triangles;
        ++accepted_;
        if (slot.used == bufferCapacity_) flush(slot, index);
    }
}

void BucketWriter::flush(Slot& slot, size_t index) {
    size_t written = 0;
    int err = writeAll(slot.fd, slot.buffer.get(), slot.used, written);
    bytesWritten_ += written;
    slot.bytes += written;
    if (err) failWrite(index, err, slot.used - written);
    slot.used = 0;
}

void BucketWriter::failWrite(size_t index, int err, uint64_t unwritten) {
    failed_ = true;
    // What is still owed: the rest of this buffer, every other buffer, and, when the total is
    // known, every triangle not yet handed to write().
    uint64_t needed = unwritten;
    for (size_t i = 0; i < slots_.size(); ++i)
        if (i != index) needed += slots_[i].used;
    bool exact = expected_.has_value();
    if (exact && *expected_ > accepted_) needed += (*expected_ - accepted_) * kBucketRecordBytes;
    std::string label = slotLabel(index);
    discard();
    fail(directory_, "cannot write {}: {} (needed {}{} more bytes)", label, errnoText(err), exact ? "" : "at least ",
         needed);
}

void BucketWriter::discard() noexcept {
    for (Slot& slot : slots_) {
        if (slot.fd >= 0) ::close(slot.fd);
        slot.fd = -1;
        if (!slot.path.empty()) ::unlink(slot.path.c_str());
        if (slot.registered) unregisterTempFile(slot.path);
        slot.registered = false;
        slot.buffer.reset();
        slot.used = 0;
    }
    allocatedBufferBytes_ = 0;
    if (directoryExists_) {
        // Kept mode may have left a manifest if finish() failed after writing it.
        ::unlink((directory_ + "/manifest.tsv").c_str());
        ::rmdir(directory_.c_str());
        directoryExists_ = false;
    }
}

BucketSet BucketWriter::finish() {
    if (failed_) fail(directory_, "cannot finish buckets: an earlier write failed");
    if (finished_) throw std::logic_error("BucketWriter::finish called twice");
    for (size_t i = 0; i < slots_.size(); ++i)
        if (slots_[i].used > 0) flush(slots_[i], i);

    BucketSet set;
    set.directory_ = directory_;
    set.kept_ = options_.keep;
    set.ranges_ = ranges_;
    for (size_t i = 0; i < slots_.size(); ++i) {
        const Slot& slot = slots_[i];
        BucketInfo info;
        info.range = i % ranges_.count();
        info.alphaMatte = i >= ranges_.count();
        info.areas = ranges_.range(info.range);
        info.triangles = slot.triangles;
        info.bytes = slot.bytes;
        info.path = slot.path;
        (info.alphaMatte ? set.alphaMatteTriangles_ : set.opaqueTriangles_) += slot.triangles;
        set.bytes_ += slot.bytes;
        set.buckets_.push_back(std::move(info));
    }

    if (options_.keep) {
        // A few hundred bytes describing the files, for whoever asked to keep them.
        std::string manifest = "file\tkind\trange\tmin_area\tmax_area\ttriangles\tbytes\n";
        for (const BucketInfo& b : set.buckets_)
            manifest += fmt::format("{}\t{}\t{}\t{}\t{}\t{}\t{}\n", std::filesystem::path(b.path).filename().string(),
                                    b.alphaMatte ? "alpha-matte" : "opaque", b.range, b.areas.lower, b.areas.upper,
                                    b.triangles, b.bytes);
        writeFileAtomically(directory_ + "/manifest.tsv",
                            std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(manifest.data()), manifest.size()));
    }

    // From here nothing can fail: hand the descriptors over and stop tracking kept files,
    // which are now a complete set the user asked to keep.
    for (Slot& slot : slots_) {
        set.fds_.push_back(slot.fd);
        slot.fd = -1;
        if (slot.registered) unregisterTempFile(slot.path);
        slot.registered = false;
        slot.buffer.reset();
    }
    allocatedBufferBytes_ = 0;
    finished_ = true;
    return set;
}

// ---------------------------------------------------------------------------------------------
// BucketReplaySource

BucketReplaySource::BucketReplaySource(std::shared_ptr<const BucketSet> set, size_t readBufferBytes)
    : set_(std::move(set)) {
    if (!set_) throw std::invalid_argument("BucketReplaySource: no bucket set");
    size_t capacity = std::max(readBufferBytes - readBufferBytes % kBucketRecordBytes, kBucketRecordBytes);
    buffer_.resize(capacity);
    for (size_t i = 0; i < set_->buckets().size(); ++i)
        if (set_->buckets()[i].bytes > 0)
            ::posix_fadvise(set_->fileDescriptor(i), 0, 0, POSIX_FADV_SEQUENTIAL);
    skipEmptyBuckets();
}

void BucketReplaySource::rewind() {
    bucket_ = 0;
    offset_ = 0;
    bufferBegin_ = bufferEnd_ = 0;
    ++passes_;
    skipEmptyBuckets();
}

void BucketReplaySource::skipEmptyBuckets() {
    const auto& buckets = set_->buckets();
    while (bucket_ < buckets.size() && offset_ >= buckets[bucket_].bytes) {
        ++bucket_;
        offset_ = 0;
    }
}

size_t BucketReplaySource::readFile(void* dst, size_t bytes) {
    const int fd = set_->fileDescriptor(bucket_);
    Stopwatch clock;
    size_t done = 0;
    while (done < bytes) {
        ssize_t n = ::pread(fd, static_cast<uint8_t*>(dst) + done, bytes - done, static_cast<off_t>(offset_ + done));
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) fail(set_->directory(), "cannot read bucket {}: {}", bucket_, errnoText(errno));
        if (n == 0)
            fail(set_->directory(), "bucket {} is shorter than written ({} of {} bytes)", bucket_, offset_ + done,
                 set_->buckets()[bucket_].bytes);
        done += static_cast<size_t>(n);
    }
    readSeconds_ += clock.seconds();
    bytesRead_ += bytes;
    offset_ += bytes;
    return bytes;
}

size_t BucketReplaySource::read(std::span<Triangle> out) {
    const auto& buckets = set_->buckets();
    auto* dst = reinterpret_cast<uint8_t*>(out.data());
    const size_t want = out.size() * kBucketRecordBytes;
    size_t got = 0;
    while (got < want) {
        if (bufferBegin_ < bufferEnd_) {
            size_t take = std::min(want - got, bufferEnd_ - bufferBegin_);
            std::memcpy(dst + got, buffer_.data() + bufferBegin_, take);
            bufferBegin_ += take;
            got += take;
            continue;
        }
        skipEmptyBuckets();
        if (bucket_ >= buckets.size()) break;
        const uint64_t left = buckets[bucket_].bytes - offset_;
        if (want - got >= buffer_.size()) {
            // Large request: straight into the caller's memory, no copy.
            got += readFile(dst + got, static_cast<size_t>(std::min<uint64_t>(want - got, left)));
        } else {
            bufferBegin_ = 0;
            bufferEnd_ = readFile(buffer_.data(), static_cast<size_t>(std::min<uint64_t>(buffer_.size(), left)));
        }
    }
    return got / kBucketRecordBytes;
}

}  // namespace penumbra
