#include "stream/ObjReader.h"

#include "stream/util/Error.h"
#include "stream/util/InputFile.h"
#include "stream/util/Memory.h"
#include "stream/util/Progress.h"
#include "stream/ObjTokenizer.h"
#include "stream/PolygonTriangulation.h"
#include "stream/util/RegularFile.h"
#include "stream/VertexStore.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <new>
#include <optional>
#include <string_view>
#include <unordered_set>

namespace penumbra {

namespace {

/// Reads a file line by line with a reusable buffer, tracking byte offsets (to resume the
/// streaming pass) and line numbers (for messages). Only next() and seek() need it open.
class LineReader {
public:
    /// A line buffer up to this size is kept between passes; a larger one is freed.
    static constexpr size_t kKeptBufferBytes = size_t(1) << 16;
    explicit LineReader(const std::string& path) : path_(path) { open(); }
    ~LineReader() {
        close();
        std::free(buffer_);
    }
    LineReader(const LineReader&) = delete;
    LineReader& operator=(const LineReader&) = delete;

    /// @brief The next line as objLineText() gives it; false at the end of the file.
    bool next(std::string_view& line) {
        lineStart_ = offset_;
        errno = 0;
        ssize_t length = ::getline(&buffer_, &capacity_, file_);
        if (length < 0) {
            // getline(3) gives -1 for a line it could not grow its buffer for, too: that is no end
            // of the file (the rest of the mesh was dropped, exit 0, under an address-space limit).
            if (errno == ENOMEM && !std::feof(file_)) failLineTooLong();
            if (std::ferror(file_) || !std::feof(file_)) fail(where(), "read error: {}", std::strerror(errno));
            return false;
        }
        offset_ += static_cast<uint64_t>(length);
        lastLength_ = static_cast<uint64_t>(length);
        ++lineNumber_;
        line = objLineText(std::string_view(buffer_, static_cast<size_t>(length)), lineNumber_);
        return true;
    }

    /// @brief The line at lineStart_ could not be held: an error naming it and its length (read
    /// again in blocks, without holding it), so that the limit to give can be worked out.
    [[noreturn]] void failLineTooLong() {
        const ObjLocation at{path_, lineNumber_ + 1};
        uint64_t length = 0;
        char block[1 << 14];
        if (::fseeko(file_, static_cast<off_t>(lineStart_), SEEK_SET) == 0) {
            while (size_t n = std::fread(block, 1, sizeof(block), file_)) {
                const void* end = std::memchr(block, '\n', n);
                length += end ? size_t(static_cast<const char*>(end) - block) + 1 : n;
                if (end) break;
            }
        }
        fail(at.text(), "a line of {} bytes does not fit in memory: reading it holds up to {}; give the process more memory",
             length, formatBytes(2 * length));
    }

    /// @brief Opens the file (again), reading from its start.
    void open() {
        close();
        file_ = std::fopen(path_.c_str(), "rb");
        if (!file_) fail(path_, "cannot open: {}", std::strerror(errno));
        offset_ = lineStart_ = lineNumber_ = 0;
    }

    /// @brief Releases the descriptor between passes, so that a scene of many files does not
    /// hold one open per file.
    void close() {
        if (file_) std::fclose(file_);
        file_ = nullptr;
        if (capacity_ > kKeptBufferBytes) {  // one long line must not hold its buffer through the bake
            std::free(buffer_);
            buffer_ = nullptr, capacity_ = 0;
        }
    }

    bool isOpen() const { return file_ != nullptr; }

    /// @brief Continues reading at @p offset, which is the start of line @p lineNumber + 1.
    void seek(uint64_t offset, uint64_t lineNumber) {
        if (::fseeko(file_, static_cast<off_t>(offset), SEEK_SET) != 0)
            fail(path_, "cannot seek: {}", std::strerror(errno));
        std::clearerr(file_);
        offset_ = offset;
        lineNumber_ = lineNumber;
    }

    /// Byte offset of the line last returned by next().
    uint64_t lineStart() const { return lineStart_; }
    /// Bytes of the line last returned by next(), with its line end and any comment.
    uint64_t lastLength() const { return lastLength_; }
    /// 1-based number of the line last returned by next().
    uint64_t lineNumber() const { return lineNumber_; }
    /// "path:line" of the line last returned, the location every message starts with.
    std::string where() const { return location().text(); }
    /// The same, built only when a message needs it.
    ObjLocation location() const { return {path_, lineNumber_}; }

private:
    std::string path_;
    std::FILE* file_ = nullptr;
    char* buffer_ = nullptr;  // owned by getline(3), hence malloc/free
    size_t capacity_ = 0;
    uint64_t offset_ = 0;
    uint64_t lineStart_ = 0;
    uint64_t lineNumber_ = 0;
    uint64_t lastLength_ = 0;
};

/// One warning when the OBJ's material libraries (beside it) cut faces out with `map_d`: materials
/// are not read, so cut-out foliage cards cast as whole quads, which a user sees only as too
/// much shadow.
void warnCutOutsIgnored(const std::string& obj, const std::vector<std::string>& libraries) {
    const std::filesystem::path dir = std::filesystem::path(obj).parent_path();
    for (const std::string& library : libraries) {
        std::ifstream in(dir / library);
        for (std::string line; in && std::getline(in, line);) {
            const size_t start = line.find_first_not_of(" \t");
            if (start == std::string::npos || line.compare(start, 6, "map_d ") != 0) continue;
            printWarning("{}: its materials ({}) cut faces out with map_d, which is not read: those faces cast as whole "
                         "polygons (convert the mesh to glTF with alphaMode \"MASK\" for cut-outs)", obj, library);
            return;
        }
    }
}

/// The size of @p path, which must open as a regular file (a directory would fail only when read).
uint64_t regularFileSize(const std::string& path) { return RegularFile(path).size(); }

class ObjSource final : public TriangleSource {
public:
    ObjSource(const std::string& path, std::vector<std::string> parts)
        : path_(path), fileBytes_(regularFileSize(path)), stamp_(FileStamp::of(path)), lines_(path), vertices_(path),
          parts_(std::move(parts)) {
        lines_.close();  // opened again by the scan, on the first read() or sizeHint()
    }

    size_t read(std::span<Triangle> out) override;
    void rewind() override;
    std::string name() const override { return path_; }
    std::optional<uint64_t> sizeHint() const override {
        // The scan may be running on a read-ahead thread (PrefetchSource): once, for both.
        std::call_once(scanOnce_, [this] { const_cast<ObjSource*>(this)->scan(); });
        return triangleCount_;
    }
    std::optional<uint64_t> knownSize() const override {
        return scanned_ ? std::optional<uint64_t>(triangleCount_) : std::nullopt;
    }
    /// The vertex store's bound for the vertices the scan stored, or before it has finished for
    /// those the file can hold (a `v` line has at least 8 bytes: real exports have 30-40, so that
    /// bound is 4-5x what a scene of many mesh files keeps), and what reading a line holds: the
    /// line (getline(3) grows its buffer by doubling) and, for a face, its corners and their
    /// triangulation. Known once scan() has run (on opening); until then the line buffer's usual
    /// size.
    uint64_t residentBytes() const override {
        const uint64_t stored = storedVertices_.load();
        return VertexStore::residentBytes(stored != kNotScanned ? stored : fileBytes_ / 8) + lineBytes();
    }
    std::string residentDetail() const override {
        if (lineBytes() < kNotableResidentBytes) return {};
        return fmt::format("{}: reading its longest line ({} bytes) or largest face ({} corners) holds {}", path_, longestLine_,
                           mostCorners_, formatBytes(lineBytes()));
    }

private:
    void scan();
    bool selected(std::string_view part) const;
    bool nextPolygon();
    void counts(uint64_t c[3]) const { c[0] = verticesSeen_, c[1] = c[2] = UINT32_MAX; }
    /// A face's corner (parsed, its position, its place in the projection and the ear ring) and
    /// triangle, twice for vectors that grew by doubling.
    static constexpr uint64_t kFaceBytesPerCorner = 2 * (sizeof(ObjCorner) + sizeof(glm::vec3) + 16 + 4 + 12);
    uint64_t lineBytes() const { return std::max<uint64_t>(1u << 16, 2 * longestLine_) + mostCorners_ * kFaceBytesPerCorner; }

    std::string path_;
    uint64_t fileBytes_;
    FileStamp stamp_;  ///< the version checked: every pass reads it (nextPolygon())
    LineReader lines_;
    VertexStore vertices_;  // the only per-mesh data kept, in bounded memory
    std::vector<std::string> parts_;  // o/g groups streamed; empty: all
    mutable std::once_flag scanOnce_;
    std::atomic<bool> scanned_{false};
    static constexpr uint64_t kNotScanned = UINT64_MAX;
    std::atomic<uint64_t> storedVertices_{kNotScanned};  ///< the store's count once scan() is through
    uint64_t triangleCount_ = 0;
    uint64_t longestLine_ = 0;  // bytes, with its line end (scan())
    uint64_t mostCorners_ = 0;  // of any face (scan())

    // Where the streaming pass starts: the first `f` line and what precedes it.
    bool hasFaces_ = false;
    uint64_t firstFaceOffset_ = 0;
    uint64_t linesBeforeFirstFace_ = 0;
    uint64_t verticesBeforeFirstFace_ = 0;
    std::string partBeforeFirstFace_;

    // Streaming pass state.
    uint64_t verticesSeen_ = 0;      // `v` lines passed so far: the range indices may address
    std::string part_;               // the o/g group of the faces being read
    std::vector<ObjCorner> polygon_; // the face being triangulated
    std::vector<glm::vec3> corners_; // its corners' positions
    std::vector<std::array<uint32_t, 3>> faceTriangles_;  // triangulatePolygon() of polygon_
    size_t nextTriangle_ = 0;        // the next of faceTriangles_ to hand out
    uint64_t emitted_ = 0;           // triangles this pass handed out, against the scan's count
    bool finished_ = false;
};

bool ObjSource::selected(std::string_view part) const {
    return parts_.empty() || std::find(parts_.begin(), parts_.end(), part) != parts_.end();
}

/// One pass over the file: every statement is checked (so all errors surface before the first
/// triangle is handed out and sizeHint() is exact), vertices are stored, faces are counted.
void ObjSource::scan() {
    scanned_ = true;
    lines_.open();
    // A phase of its own where the opener asked for one (OpeningProgress) and the file is large
    // enough to be waited for (about 120 MB/s: from a quarter second up; a 20 GB file takes
    // minutes here, before any triangle is handed out). Its bytes are the work.
    OpeningPhase progress("check " + std::filesystem::path(path_).filename().string(), fileBytes_);
    std::string_view line;
    std::vector<ObjCorner> corners;
    uint64_t counts[3] = {0, 0, 0};  // v, vt, vn defined so far
    std::string part;
    // Part names, for the error about a missing one: kept only when parts are selected, and in a
    // hash (a linear search made a file of 160,000 groups take 18 s to check).
    std::unordered_set<std::string> seen;
    std::vector<std::string> materialLibraries;  // mtllib names, for warnCutOutsIgnored()
    while (lines_.next(line)) {
        progress.advance(lines_.lineStart());
        longestLine_ = std::max(longestLine_, lines_.lastLength());
        ObjTokens tokens(line);
        std::string_view keyword = tokens.next();
        if (keyword == "v") {
            vertices_.push(parseObjVector(tokens, 3, "vertex", lines_.location()));
            if (++counts[0] > std::numeric_limits<uint32_t>::max()) fail(lines_.where(), "more than 2^32 vertices");
        } else if (keyword == "vt" || keyword == "vn") {
            // Not kept for blockers, but read exactly as the receiver meshes read them, so that one
            // file is good or bad for both.
            parseObjVector(tokens, keyword == "vt" ? 2 : 3, keyword == "vt" ? "texture coordinate" : "normal", lines_.location());
            ++counts[keyword == "vt" ? 1 : 2];
        } else if (keyword == "o" || keyword == "g") {
            part = std::string(tokens.rest());
            if (!parts_.empty()) seen.insert(part);
        } else if (keyword == "mtllib") {
            materialLibraries.emplace_back(tokens.rest());
        } else if (keyword == "f") {
            parseObjFace(tokens, counts, corners, lines_.location());
            mostCorners_ = std::max<uint64_t>(mostCorners_, corners.size());
            if (!hasFaces_) {
                hasFaces_ = true;
                firstFaceOffset_ = lines_.lineStart();
                linesBeforeFirstFace_ = lines_.lineNumber() - 1;
                verticesBeforeFirstFace_ = counts[0];
                partBeforeFirstFace_ = part;
            }
            if (selected(part)) triangleCount_ += corners.size() - 2;
        }
    }
    progress.finish();
    warnCutOutsIgnored(path_, materialLibraries);
    for (const std::string& wanted : parts_)
        if (!seen.count(wanted))
            fail(path_, "has no o/g group named \"{}\" (it has {} group{})", wanted, seen.size(), seen.size() == 1 ? "" : "s");
    lines_.close();
    storedVertices_ = vertices_.size();
    rewind();
}

void ObjSource::rewind() {
    // The file is reopened by the first read() of the next pass.
    lines_.close();
    faceTriangles_.clear();
    nextTriangle_ = 0;
    finished_ = scanned_ && !hasFaces_;
    verticesSeen_ = verticesBeforeFirstFace_;
    part_ = partBeforeFirstFace_;
    emitted_ = 0;
}

/// Advances the streaming pass to the next face of a selected part; false at the end of the file.
bool ObjSource::nextPolygon() {
    if (!lines_.isOpen()) {
        // Every pass reads the file the scan checked: one cut or rewritten since (a bake's passes
        // are minutes apart on a large file) gave another mesh, and exit 0.
        if (regularFileSize(path_) != fileBytes_)
            fail(path_, "file changed while it was being read: it had {} bytes when checked, {} now", fileBytes_,
                 regularFileSize(path_));
        requireUnchangedFile(path_, stamp_);  // the same size, rewritten or replaced
        lines_.open();
        lines_.seek(firstFaceOffset_, linesBeforeFirstFace_);
    }
    std::string_view line;
    uint64_t counts[3];
    while (lines_.next(line)) {
        ObjTokens tokens(line);
        std::string_view keyword = tokens.next();
        if (keyword == "v") {
            // Already parsed and validated by scan(); only the count matters here.
            if (++verticesSeen_ > vertices_.size()) fail(lines_.where(), "file changed while it was being read");
        } else if (keyword == "o" || keyword == "g") {
            part_ = std::string(tokens.rest());
        } else if (keyword == "f" && selected(part_)) {
            this->counts(counts);  // vt and vn were checked by scan()
            parseObjFace(tokens, counts, polygon_, lines_.location());
            corners_.resize(polygon_.size());
            for (size_t c = 0; c < polygon_.size(); ++c) corners_[c] = vertices_[uint64_t(polygon_[c].v)];
            triangulatePolygon(corners_, faceTriangles_);
            nextTriangle_ = 0;
            return true;
        }
    }
    return false;
}

size_t ObjSource::read(std::span<Triangle> out) {
    std::call_once(scanOnce_, [this] { scan(); });
    size_t written = 0;
    while (written < out.size() && !finished_) {
        if (nextTriangle_ >= faceTriangles_.size() && !nextPolygon()) {
            finished_ = true;
            lines_.close();
            if (emitted_ != triangleCount_)
                fail(path_, "file changed while it was being read: {} triangles when checked, {} in this pass", triangleCount_, emitted_);
            break;
        }
        for (; nextTriangle_ < faceTriangles_.size() && written < out.size(); ++nextTriangle_, ++emitted_) {
            const std::array<uint32_t, 3>& f = faceTriangles_[nextTriangle_];
            Triangle& t = out[written++];
            t.v = {corners_[f[0]], corners_[f[1]], corners_[f[2]]};
            t.flags = 0;
        }
    }
    return written;
}

}  // namespace

TriangleSourcePtr openObj(const std::string& path, const std::vector<std::string>& parts) {
    return std::make_unique<ObjSource>(path, parts);
}

}  // namespace penumbra
