#include "stream/ObjReader.h"

#include "stream/Error.h"

#include <cerrno>
#include <cfloat>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string_view>

namespace penumbra {

namespace {

/// Reads a file line by line with a reusable buffer, tracking byte offsets (to resume the
/// streaming pass) and line numbers (for messages). Only next() and seek() need it open.
class LineReader {
public:
    explicit LineReader(const std::string& path) : path_(path) { open(); }
    ~LineReader() {
        close();
        std::free(buffer_);
    }
    LineReader(const LineReader&) = delete;
    LineReader& operator=(const LineReader&) = delete;

    /// @brief The next line without its "\n" or "\r\n"; false at the end of the file.
    bool next(std::string_view& line) {
        lineStart_ = offset_;
        ssize_t length = ::getline(&buffer_, &capacity_, file_);
        if (length < 0) {
            if (std::ferror(file_)) fail(where(), "read error: {}", std::strerror(errno));
            return false;
        }
        offset_ += static_cast<uint64_t>(length);
        ++lineNumber_;
        size_t end = static_cast<size_t>(length);
        while (end > 0 && (buffer_[end - 1] == '\n' || buffer_[end - 1] == '\r')) --end;
        line = std::string_view(buffer_, end);
        return true;
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
    /// 1-based number of the line last returned by next().
    uint64_t lineNumber() const { return lineNumber_; }
    /// "path:line" of the line last returned, the location every message starts with.
    std::string where() const { return path_ + ":" + std::to_string(lineNumber_); }

private:
    std::string path_;
    std::FILE* file_ = nullptr;
    char* buffer_ = nullptr;  // owned by getline(3), hence malloc/free
    size_t capacity_ = 0;
    uint64_t offset_ = 0;
    uint64_t lineStart_ = 0;
    uint64_t lineNumber_ = 0;
};

/// Splits a line into whitespace-separated tokens, stopping at a '#' comment.
class Tokens {
public:
    explicit Tokens(std::string_view line) : rest_(line.substr(0, line.find('#'))) {}

    /// @brief The next token, or an empty view when the line is used up.
    std::string_view next() {
        size_t begin = rest_.find_first_not_of(" \t\v\f");
        if (begin == std::string_view::npos) return {};
        size_t end = rest_.find_first_of(" \t\v\f", begin);
        if (end == std::string_view::npos) end = rest_.size();
        std::string_view token = rest_.substr(begin, end - begin);
        rest_.remove_prefix(end);
        return token;
    }

private:
    std::string_view rest_;
};

/// from_chars does not accept a leading '+', which some exporters write ("+-1" stays invalid).
std::string_view withoutPlus(std::string_view token) {
    if (token.size() > 1 && token[0] == '+' && token[1] != '-' && token[1] != '+') token.remove_prefix(1);
    return token;
}

/// Parses a coordinate, rounding straight from decimal to float so that a float printed in
/// shortest round-trip form reads back with the same bits.
float parseCoordinate(std::string_view token, const LineReader& lines) {
    std::string_view digits = withoutPlus(token);
    float value = 0;
    auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (end != digits.data() + digits.size() || (error != std::errc() && error != std::errc::result_out_of_range))
        fail(lines.where(), "unparsable number '{}'", token);
    if (error == std::errc::result_out_of_range) {
        // from_chars reports overflow and underflow alike. Underflow (to a denormal or zero) is
        // harmless, overflow is an infinite coordinate; a double parse tells them apart (strtod
        // would depend on the locale's decimal point). Beyond double range, the sign of the
        // exponent decides.
        double wide = 0;
        if (std::from_chars(digits.data(), digits.data() + digits.size(), wide).ec != std::errc()) {
            bool tiny = digits.find("e-") != std::string_view::npos || digits.find("E-") != std::string_view::npos;
            wide = tiny ? 0.0 : HUGE_VAL;
        }
        if (!(std::abs(wide) <= FLT_MAX)) fail(lines.where(), "non-finite coordinate '{}'", token);
        value = std::copysign(static_cast<float>(wide), digits[0] == '-' ? -1.0f : 1.0f);
    }
    if (!std::isfinite(value)) fail(lines.where(), "non-finite coordinate '{}'", token);
    return value;
}

/// Parses the integer fields of a face corner; false when @p token is not an integer.
bool parseInteger(std::string_view token, int64_t& value) {
    token = withoutPlus(token);
    auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
    return error == std::errc() && end == token.data() + token.size();
}

/// @brief Parses the corners of an `f` statement into zero-based vertex indices.
/// @param vertexCount vertices defined above this line: the range valid indices address.
void parseFace(Tokens& tokens, size_t vertexCount, std::vector<uint32_t>& corners, const LineReader& lines) {
    corners.clear();
    for (std::string_view corner = tokens.next(); !corner.empty(); corner = tokens.next()) {
        // "v", "v/vt", "v//vn" or "v/vt/vn": vt and vn must be integers when present, but only
        // v is used (texture and normal arrays are not kept).
        std::string_view fields[3];
        size_t fieldCount = 0;
        std::string_view rest = corner;
        while (true) {
            size_t slash = rest.find('/');
            if (fieldCount == 3) fail(lines.where(), "unparsable face corner '{}'", corner);
            fields[fieldCount++] = rest.substr(0, slash);
            if (slash == std::string_view::npos) break;
            rest.remove_prefix(slash + 1);
        }
        int64_t index = 0, unused = 0;
        if (!parseInteger(fields[0], index)) fail(lines.where(), "unparsable face corner '{}'", corner);
        for (size_t i = 1; i < fieldCount; ++i)
            if (!fields[i].empty() && !parseInteger(fields[i], unused))
                fail(lines.where(), "unparsable face corner '{}'", corner);

        if (index == 0) fail(lines.where(), "face index 0 is invalid (OBJ indices start at 1)");
        // Negative indices count back from the last vertex defined above the face.
        int64_t count = static_cast<int64_t>(vertexCount);
        int64_t resolved = index > 0 ? index - 1 : count + index;
        if (resolved < 0 || resolved >= count)
            fail(lines.where(), "face index {} out of range ({} vertices)", index, vertexCount);
        corners.push_back(static_cast<uint32_t>(resolved));
    }
    if (corners.size() < 3)
        fail(lines.where(), "face has {} corner{} (needs at least 3)", corners.size(),
             corners.size() == 1 ? "" : "s");
}

class ObjSource final : public TriangleSource {
public:
    explicit ObjSource(const std::string& path) : path_(path), lines_(path) { scan(); }

    size_t read(std::span<Triangle> out) override;
    void rewind() override;
    std::string name() const override { return path_; }
    std::optional<uint64_t> sizeHint() const override { return triangleCount_; }

private:
    void scan();
    bool nextPolygon();

    std::string path_;
    LineReader lines_;
    std::vector<glm::vec3> vertices_;  // the only per-mesh data kept in memory
    uint64_t triangleCount_ = 0;

    // Where the streaming pass starts: the first `f` line and what precedes it.
    bool hasFaces_ = false;
    uint64_t firstFaceOffset_ = 0;
    uint64_t linesBeforeFirstFace_ = 0;
    size_t verticesBeforeFirstFace_ = 0;

    // Streaming pass state.
    size_t verticesSeen_ = 0;        // `v` lines passed so far: the range indices may address
    std::vector<uint32_t> polygon_;  // the face being fan-triangulated
    size_t nextFan_ = 0;             // next fan triangle is (0, nextFan_, nextFan_ + 1)
    bool finished_ = false;
};

void ObjSource::scan() {
    std::string_view line;
    std::vector<uint32_t> corners;
    while (lines_.next(line)) {
        Tokens tokens(line);
        std::string_view keyword = tokens.next();
        if (keyword == "v") {
            glm::vec3 p;
            for (int axis = 0; axis < 3; ++axis) {
                std::string_view token = tokens.next();
                if (token.empty())
                    fail(lines_.where(), "vertex has {} coordinate{} (needs 3)", axis, axis == 1 ? "" : "s");
                p[axis] = parseCoordinate(token, lines_);
            }
            // A fourth value (w) or three more (vertex colour) are allowed but must be numbers.
            for (std::string_view extra = tokens.next(); !extra.empty(); extra = tokens.next())
                parseCoordinate(extra, lines_);
            if (vertices_.size() == std::numeric_limits<uint32_t>::max())
                fail(lines_.where(), "more than {} vertices", vertices_.size());
            vertices_.push_back(p);
        } else if (keyword == "f") {
            parseFace(tokens, vertices_.size(), corners, lines_);
            if (!hasFaces_) {
                hasFaces_ = true;
                firstFaceOffset_ = lines_.lineStart();
                linesBeforeFirstFace_ = lines_.lineNumber() - 1;
                verticesBeforeFirstFace_ = vertices_.size();
            }
            triangleCount_ += corners.size() - 2;
        }
    }
    vertices_.shrink_to_fit();
    rewind();
}

void ObjSource::rewind() {
    // The file is reopened by the first read() of the next pass.
    lines_.close();
    polygon_.clear();
    nextFan_ = 0;
    finished_ = !hasFaces_;
    verticesSeen_ = verticesBeforeFirstFace_;
}

/// Advances the streaming pass to the next face; false at the end of the file.
bool ObjSource::nextPolygon() {
    if (!lines_.isOpen()) {
        lines_.open();
        lines_.seek(firstFaceOffset_, linesBeforeFirstFace_);
    }
    std::string_view line;
    while (lines_.next(line)) {
        Tokens tokens(line);
        std::string_view keyword = tokens.next();
        if (keyword == "v") {
            // Already parsed and validated by scan(); only the count matters here.
            if (++verticesSeen_ > vertices_.size()) fail(lines_.where(), "file changed while it was being read");
        } else if (keyword == "f") {
            parseFace(tokens, verticesSeen_, polygon_, lines_);
            nextFan_ = 1;
            return true;
        }
    }
    return false;
}

size_t ObjSource::read(std::span<Triangle> out) {
    size_t written = 0;
    while (written < out.size() && !finished_) {
        if (nextFan_ + 1 >= polygon_.size() && !nextPolygon()) {
            finished_ = true;
            lines_.close();
            break;
        }
        for (; nextFan_ + 1 < polygon_.size() && written < out.size(); ++nextFan_) {
            Triangle& t = out[written++];
            t.v = {vertices_[polygon_[0]], vertices_[polygon_[nextFan_]], vertices_[polygon_[nextFan_ + 1]]};
            t.flags = 0;
        }
    }
    return written;
}

}  // namespace

TriangleSourcePtr openObj(const std::string& path) { return std::make_unique<ObjSource>(path); }

}  // namespace penumbra
