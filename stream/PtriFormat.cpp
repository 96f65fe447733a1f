#include "stream/PtriFormat.h"
#include "stream/Translucency.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/InputFile.h"

#include <glm/common.hpp>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace penumbra {

// The format is defined little-endian and written by copying Triangle records verbatim.
static_assert(std::endian::native == std::endian::little, ".ptri I/O assumes a little-endian host");
static_assert(sizeof(Triangle) == kPtriTriangleBytes);

uint32_t fnv1a32(const void* data, size_t size, uint32_t hash) {
    const auto* bytes = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < size; ++i) hash = (hash ^ bytes[i]) * 16777619u;
    return hash;
}

uint32_t PtriInfo::chunkTriangles(uint64_t k) const {
    uint64_t before = k * chunkSize;
    return static_cast<uint32_t>(std::min<uint64_t>(chunkSize, triangles - before));
}

uint64_t PtriInfo::fileBytes() const {
    return kPtriHeaderBytes + chunkCount() * kPtriChunkHeaderBytes + triangles * kPtriTriangleBytes;
}

namespace {

/// The header as laid out on disk (see the contract in PtriFormat.h).
struct HeaderBytes {
    unsigned char bytes[kPtriHeaderBytes] = {};

    template <typename T>
    void put(size_t offset, const T& value) { std::memcpy(bytes + offset, &value, sizeof(T)); }
    template <typename T>
    T get(size_t offset) const {
        T value;
        std::memcpy(&value, bytes + offset, sizeof(T));
        return value;
    }
};

HeaderBytes encodeHeader(const PtriInfo& info) {
    HeaderBytes h;
    std::memcpy(h.bytes, kPtriMagic, 4);
    h.put(4, kPtriVersion);
    h.put(8, info.triangles);
    for (int i = 0; i < 3; ++i) h.put(16 + 4 * i, info.lo[i]);
    for (int i = 0; i < 3; ++i) h.put(28 + 4 * i, info.hi[i]);
    h.put(40, info.chunkSize);
    h.put(44, fnv1a32(h.bytes, 44));
    return h;
}

/// Hash of a chunk: its count field, then its payload.
uint32_t chunkChecksum(uint32_t count, const Triangle* triangles) {
    uint32_t hash = fnv1a32(&count, sizeof count);
    return fnv1a32(triangles, count * kPtriTriangleBytes, hash);
}

/// @brief Reads up to @p size bytes; returns how many were available before the end of file.
size_t readFully(std::FILE* file, void* data, size_t size, const std::string& path) {
    size_t got = std::fread(data, 1, size, file);
    if (got < size && std::ferror(file)) fail(path, "read error: {}", std::strerror(errno));
    return got;
}

struct OpenFile {
    std::FILE* file;
    PtriInfo info;
    FileStamp stamp;  ///< the version verified
};

/// Opens @p path and verifies everything the header promises (see readPtriHeader).
OpenFile openVerified(const std::string& path) {
    std::FILE* file = openInputStream(path);  // regular files only: a FIFO would block here
    // Closes the file on every throw below.
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> guard(file, &std::fclose);

    struct stat status {};
    if (::fstat(::fileno(file), &status) != 0) fail(path, "cannot stat: {}", std::strerror(errno));
    if (!S_ISREG(status.st_mode)) fail(path, "not a regular file");
    uint64_t size = static_cast<uint64_t>(status.st_size);

    HeaderBytes h;
    size_t got = readFully(file, h.bytes, kPtriHeaderBytes, path);
    if (got >= 4 && std::memcmp(h.bytes, kPtriMagic, 4) != 0) fail(path, "not a .ptri file (bad magic)");
    if (got < kPtriHeaderBytes)
        fail(path, "truncated header (expected {} bytes, found {})", kPtriHeaderBytes, got);
    if (uint32_t version = h.get<uint32_t>(4); version != kPtriVersion)
        fail(path, "unsupported .ptri version {} (this build reads version {})", version, kPtriVersion);
    if (h.get<uint32_t>(44) != fnv1a32(h.bytes, 44)) fail(path, "header checksum mismatch");

    PtriInfo info;
    info.triangles = h.get<uint64_t>(8);
    for (int i = 0; i < 3; ++i) info.lo[i] = h.get<float>(16 + 4 * i);
    for (int i = 0; i < 3; ++i) info.hi[i] = h.get<float>(28 + 4 * i);
    info.chunkSize = h.get<uint32_t>(40);
    if (info.chunkSize == 0 || info.chunkSize > kPtriMaxChunk)
        fail(path, "invalid chunk size {} (must be 1..{})", info.chunkSize, kPtriMaxChunk);
    // A count whose file size would not fit in 64 bits cannot describe a real file; checking it
    // first keeps fileBytes() from overflowing.
    if (info.triangles > (std::numeric_limits<uint64_t>::max() / 2) / (kPtriTriangleBytes + kPtriChunkHeaderBytes))
        fail(path, "implausible triangle count {}", info.triangles);

    uint64_t expected = info.fileBytes();
    if (size > expected)
        fail(path, "{} unexpected bytes after the last chunk (file has {}, header implies {})", size - expected,
             size, expected);
    if (size < expected) {
        // Chunks before the last are all the same size, so the damaged one is found by division.
        uint64_t fullChunkBytes = kPtriChunkHeaderBytes + uint64_t(info.chunkSize) * kPtriTriangleBytes;
        uint64_t k = std::min((size - kPtriHeaderBytes) / fullChunkBytes, info.chunkCount() - 1);
        uint64_t start = kPtriHeaderBytes + k * fullChunkBytes;
        uint64_t chunkBytes = kPtriChunkHeaderBytes + uint64_t(info.chunkTriangles(k)) * kPtriTriangleBytes;
        fail(path, "truncated in chunk {} (expected {} bytes, found {})", k, chunkBytes, size - start);
    }
    const FileStamp stamp = FileStamp::of(::fileno(file), path);
    return {guard.release(), info, stamp};
}

class PtriSource final : public TriangleSource {
public:
    explicit PtriSource(const std::string& path) : path_(path) {
        OpenFile opened = openVerified(path);
        // Closed until the first read(): a scene may open many files before streaming any.
        std::fclose(opened.file);
        info_ = opened.info, stamp_ = opened.stamp;
    }
    ~PtriSource() override { closeFile(); }
    PtriSource(const PtriSource&) = delete;
    PtriSource& operator=(const PtriSource&) = delete;

    size_t read(std::span<Triangle> out) override;
    void rewind() override;
    uint64_t skip(uint64_t count) override;
    std::string name() const override { return path_; }
    std::optional<uint64_t> sizeHint() const override { return info_.triangles; }

private:
    void loadChunk();
    void closeFile() {
        if (file_) std::fclose(file_);
        file_ = nullptr;
    }

    std::string path_;
    std::FILE* file_ = nullptr;
    PtriInfo info_;
    FileStamp stamp_;  ///< every pass reads this version (checked as the file is reopened)
    uint64_t nextChunk_ = 0;
    std::vector<Triangle> chunk_;  // the current chunk, verified
    size_t used_ = 0;              // triangles of chunk_ already handed out
};

void PtriSource::rewind() {
    closeFile();  // reopened by the next read(), which checks it is still the file read first
    nextChunk_ = 0;
    chunk_.clear();
    used_ = 0;
}

void PtriSource::loadChunk() {
    uint64_t k = nextChunk_;
    uint32_t expectedCount = info_.chunkTriangles(k);
    size_t expectedBytes = kPtriChunkHeaderBytes + size_t(expectedCount) * kPtriTriangleBytes;
    if (!file_) {
        requireUnchangedFile(path_, stamp_);
        file_ = std::fopen(path_.c_str(), "rb");
        if (!file_) fail(path_, "cannot open: {}", std::strerror(errno));
        // Every chunk before k is full, so chunk k's offset follows from the header.
        uint64_t offset = kPtriHeaderBytes + k * (kPtriChunkHeaderBytes + uint64_t(info_.chunkSize) * kPtriTriangleBytes);
        if (::fseeko(file_, static_cast<off_t>(offset), SEEK_SET) != 0)
            fail(path_, "cannot seek: {}", std::strerror(errno));
    }

    // The size was checked at open; a short read now means the file changed underneath us.
    uint32_t fields[2];
    size_t got = readFully(file_, fields, sizeof fields, path_);
    if (got < sizeof fields) fail(path_, "truncated in chunk {} (expected {} bytes, found {})", k, expectedBytes, got);
    auto [count, checksum] = std::pair(fields[0], fields[1]);
    if (count != expectedCount)
        fail(path_, "chunk {} holds {} triangles, expected {}", k, count, expectedCount);

    chunk_.resize(count);
    got = readFully(file_, chunk_.data(), size_t(count) * kPtriTriangleBytes, path_);
    if (got < size_t(count) * kPtriTriangleBytes)
        fail(path_, "truncated in chunk {} (expected {} bytes, found {})", k, expectedBytes,
             got + kPtriChunkHeaderBytes);
    if (chunkChecksum(count, chunk_.data()) != checksum) fail(path_, "checksum mismatch in chunk {}", k);
    for (size_t i = 0; i < chunk_.size(); ++i)
        if (!isFinite(chunk_[i])) fail(path_, "chunk {} triangle {} has a non-finite coordinate", k, i);
    ++nextChunk_;
    used_ = 0;
    if (nextChunk_ == info_.chunkCount()) closeFile();
}

uint64_t PtriSource::skip(uint64_t count) {
    // The rest of the loaded chunk, then whole chunks by seeking (their checksums are not read:
    // whoever reads them checks them), then into the chunk where the skip ends.
    uint64_t skipped = std::min<uint64_t>(count, chunk_.size() - used_);
    used_ += size_t(skipped);
    if (skipped < count && nextChunk_ < info_.chunkCount()) {
        const uint64_t whole = std::min((count - skipped) / info_.chunkSize, info_.chunkCount() - nextChunk_);
        // Every chunk but the last is full, so the jump over whole ones is exact.
        const uint64_t jump = nextChunk_ + whole == info_.chunkCount() ? whole - 1 : whole;
        if (jump > 0) {
            closeFile();  // reopened at nextChunk_'s offset by loadChunk()
            nextChunk_ += jump;
            skipped += jump * info_.chunkSize;
            chunk_.clear(), used_ = 0;
        }
    }
    if (skipped < count) skipped += TriangleSource::skip(count - skipped);
    return skipped;
}

size_t PtriSource::read(std::span<Triangle> out) {
    size_t written = 0;
    while (written < out.size()) {
        if (used_ == chunk_.size()) {
            if (nextChunk_ == info_.chunkCount()) break;
            loadChunk();
        }
        size_t n = std::min(out.size() - written, chunk_.size() - used_);
        std::copy_n(chunk_.begin() + static_cast<std::ptrdiff_t>(used_), n, out.begin() + static_cast<std::ptrdiff_t>(written));
        used_ += n;
        written += n;
    }
    return written;
}

}  // namespace

PtriInfo readPtriHeader(const std::string& path) {
    OpenFile opened = openVerified(path);
    std::fclose(opened.file);
    return opened.info;
}

TriangleSourcePtr openPtri(const std::string& path) { return std::make_unique<PtriSource>(path); }

PtriWriter::PtriWriter(std::string path, uint32_t chunkSize)
    : path_(std::move(path)), chunkSize_(chunkSize) {
    if (chunkSize_ == 0 || chunkSize_ > kPtriMaxChunk)
        fail(path_, "invalid chunk size {} (must be 1..{})", chunkSize_, kPtriMaxChunk);
    // AtomicFile creates the temporary and eventually puts it in place or discards it; the bytes
    // go straight to its descriptor because the header is patched in place at the end, which
    // its append-only write() cannot do.
    file_ = std::make_unique<AtomicFile>(path_);
    fd_ = file_->descriptor();
    // Placeholder header; finish() overwrites it once count and bounds are known.
    HeaderBytes placeholder;
    writeBytes(placeholder.bytes, kPtriHeaderBytes, -1);
    chunk_.reserve(chunkSize_);
}

// Without finish(), file_'s destructor discards the temporary.
PtriWriter::~PtriWriter() = default;

void PtriWriter::writeBytes(const void* data, size_t size, int64_t offset) {
    const auto* bytes = static_cast<const unsigned char*>(data);
    size_t done = 0;
    while (done < size) {
        ssize_t n = offset < 0 ? ::write(fd_, bytes + done, size - done)
                               : ::pwrite(fd_, bytes + done, size - done, static_cast<off_t>(offset + int64_t(done)));
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            // A zero-byte write without errno is how some file systems report a full disk.
            int error = n < 0 ? errno : ENOSPC;
            fail(path_, "could not write {} of {} bytes: {}", size - done, size, std::strerror(error));
        }
        done += static_cast<size_t>(n);
    }
}

void PtriWriter::write(std::span<const Triangle> triangles) {
    if (finished_) fail(path_, "write after finish()");
    for (const Triangle& t : triangles) {
        if (!isFinite(t)) fail(path_, "triangle {} has a non-finite coordinate", count_);
        // Translucent ids name this process's table (Translucency.h): meaningless in a file.
        if (isTranslucentId(alphaIdOf(t.flags)))
            fail(path_, "triangle {} is translucent (a glTF BLEND or transmission material), which .ptri files do not hold", count_);
        if (count_ == 0) lo_ = hi_ = t.v[0];
        for (const glm::vec3& p : t.v) {
            lo_ = glm::min(lo_, p);
            hi_ = glm::max(hi_, p);
        }
        chunk_.push_back(t);
        ++count_;
        if (chunk_.size() == chunkSize_) flushChunk();
    }
}

void PtriWriter::flushChunk() {
    if (chunk_.empty()) return;
    uint32_t count = static_cast<uint32_t>(chunk_.size());
    uint32_t fields[2] = {count, chunkChecksum(count, chunk_.data())};
    writeBytes(fields, sizeof fields, -1);
    writeBytes(chunk_.data(), chunk_.size() * kPtriTriangleBytes, -1);
    chunk_.clear();
}

void PtriWriter::finish() {
    if (finished_) fail(path_, "finish() called twice");
    flushChunk();
    PtriInfo info;
    info.triangles = count_;
    info.lo = lo_;
    info.hi = hi_;
    info.chunkSize = chunkSize_;
    HeaderBytes header = encodeHeader(info);
    writeBytes(header.bytes, kPtriHeaderBytes, 0);
    fd_ = -1;
    file_->commit();
    finished_ = true;
}

}  // namespace penumbra
