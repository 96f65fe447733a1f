#include "stream/Npy.h"

#include "stream/AtomicFile.h"
#include "stream/CheckedMath.h"
#include "stream/Error.h"
#include "stream/InputFile.h"

#include <fmt/ranges.h>

#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <system_error>

namespace penumbra {

namespace {

constexpr char kMagic[] = "\x93NUMPY";
constexpr size_t kMagicBytes = 6;
/// numpy aligns the start of the data to 64 bytes so memory-mapped arrays are aligned for any
/// SIMD width; we do the same so our files are indistinguishable from numpy's.
constexpr size_t kHeaderAlign = 64;

std::string errnoText(int err) { return std::error_code(err, std::generic_category()).message(); }

/// A parsed dtype string. Only what a point list or a result array can be.
struct Dtype {
    std::string normalized;  // "<f4", "|u1", ...
    char kind = 0;           // 'f', 'i', 'u', 'b'
    size_t size = 0;
};

/// Parses a dtype string; on failure returns nullopt and sets @p why.
std::optional<Dtype> parseDtype(std::string_view text, std::string& why) {
    if (text.size() < 3) {
        why = fmt::format("unsupported dtype '{}'", text);
        return std::nullopt;
    }
    char order = text[0];
    char kind = text[1];
    std::string_view digits = text.substr(2);
    size_t size = 0;
    for (char c : digits) {
        if (c < '0' || c > '9' || size > 100) {
            why = fmt::format("unsupported dtype '{}'", text);
            return std::nullopt;
        }
        size = size * 10 + static_cast<size_t>(c - '0');
    }
    bool sizeOk = false;
    switch (kind) {
        case 'f': sizeOk = size == 2 || size == 4 || size == 8; break;
        case 'i':
        case 'u': sizeOk = size == 1 || size == 2 || size == 4 || size == 8; break;
        case 'b': sizeOk = size == 1; break;
        default: break;
    }
    if (!sizeOk || (order != '<' && order != '>' && order != '|' && order != '=')) {
        why = fmt::format("unsupported dtype '{}' (supported: float, int, uint and bool)", text);
        return std::nullopt;
    }
    if (size > 1) {
        if (order == '>') {
            why = fmt::format("big-endian dtype '{}' is not supported; convert it in numpy with "
                              "array.astype('<{}{}')", text, kind, size);
            return std::nullopt;
        }
        if (order == '|') {
            why = fmt::format("dtype '{}' has no byte order but is {} bytes wide", text, size);
            return std::nullopt;
        }
        order = '<';  // '=' is native, and penumbra only runs on little-endian machines
    } else {
        order = '|';  // byte order is meaningless for one-byte types; numpy writes '|'
    }
    return Dtype{fmt::format("{}{}{}", order, kind, size), kind, size};
}

std::string shapeText(std::span<const uint64_t> shape) {
    if (shape.empty()) return "scalar";
    return fmt::format("{}", fmt::join(shape, "x"));
}

/// Product of @p shape times @p itemSize, or nullopt on overflow.
std::optional<uint64_t> byteCount(std::span<const uint64_t> shape, size_t itemSize) {
    const std::optional<uint64_t> elements = productOf(shape);
    const uint64_t factors[2] = {elements.value_or(0), itemSize};
    return elements ? productOf(factors) : std::nullopt;
}

/// Parser for the header dict. It accepts exactly the Python literal subset numpy emits
/// (and that hand-written or older numpy headers use): string keys, string / True / False
/// values, and tuples of non-negative integers (optionally with Python 2 'L' suffixes).
class HeaderParser {
public:
    HeaderParser(std::string_view text, const std::string& path) : s_(text), path_(path) {}

    struct Result {
        std::string descr;
        bool fortranOrder = false;
        std::vector<uint64_t> shape;
    };

    Result parse() {
        Result r;
        bool haveDescr = false, haveOrder = false, haveShape = false;
        skipSpace();
        expect('{', "the header must be a Python dict starting with '{'");
        for (;;) {
            skipSpace();
            if (peek() == '}') { ++pos_; break; }
            std::string key = parseString("a quoted key");
            skipSpace();
            expect(':', fmt::format("expected ':' after key '{}'", key));
            skipSpace();
            if (key == "descr") {
                if (haveDescr) bad("key 'descr' appears twice");
                if (peek() == '[')
                    bad("structured dtypes (descr is a list) are not supported; save a plain "
                        "numeric array");
                r.descr = parseString("descr to be a quoted dtype string");
                haveDescr = true;
            } else if (key == "fortran_order") {
                if (haveOrder) bad("key 'fortran_order' appears twice");
                r.fortranOrder = parseBool("fortran_order");
                haveOrder = true;
            } else if (key == "shape") {
                if (haveShape) bad("key 'shape' appears twice");
                r.shape = parseShape();
                haveShape = true;
            } else {
                bad(fmt::format("unexpected key '{}' (expected descr, fortran_order, shape)", key));
            }
            skipSpace();
            if (peek() == ',') { ++pos_; continue; }
            expect('}', "expected ',' or '}' after a value");
            break;
        }
        skipSpace();
        if (pos_ != s_.size()) bad("unexpected text after the closing '}'");
        if (!haveDescr) bad("missing key 'descr'");
        if (!haveOrder) bad("missing key 'fortran_order'");
        if (!haveShape) bad("missing key 'shape'");
        return r;
    }

private:
    [[noreturn]] void bad(const std::string& what) { fail(path_, "bad .npy header: {}", what); }

    char peek() const { return pos_ < s_.size() ? s_[pos_] : '\0'; }

    void skipSpace() {
        while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\t' || s_[pos_] == '\n' ||
                                    s_[pos_] == '\r'))
            ++pos_;
    }

    void expect(char c, const std::string& what) {
        if (peek() != c) bad(what);
        ++pos_;
    }

    std::string parseString(const char* what) {
        char quote = peek();
        if (quote != '\'' && quote != '"') bad(fmt::format("expected {}", what));
        size_t end = s_.find(quote, pos_ + 1);
        if (end == std::string_view::npos) bad("unterminated string");
        std::string out(s_.substr(pos_ + 1, end - pos_ - 1));
        pos_ = end + 1;
        return out;
    }

    bool parseBool(const char* key) {
        if (s_.substr(pos_, 4) == "True") { pos_ += 4; return true; }
        if (s_.substr(pos_, 5) == "False") { pos_ += 5; return false; }
        bad(fmt::format("{} must be True or False", key));
    }

    uint64_t parseDimension() {
        if (peek() < '0' || peek() > '9') bad("shape entries must be non-negative integers");
        uint64_t v = 0;
        while (peek() >= '0' && peek() <= '9') {
            uint64_t digit = static_cast<uint64_t>(peek() - '0');
            if (v > (std::numeric_limits<uint64_t>::max() - digit) / 10) bad("shape entry is too large");
            v = v * 10 + digit;
            ++pos_;
        }
        if (peek() == 'L') ++pos_;  // Python 2 long literal, written by numpy under Python 2
        return v;
    }

    std::vector<uint64_t> parseShape() {
        expect('(', "shape must be a tuple such as (1000, 3)");
        std::vector<uint64_t> dims;
        bool trailingComma = false;
        for (;;) {
            skipSpace();
            if (peek() == ')') { ++pos_; break; }
            if (dims.size() >= 32) bad("shape has more than 32 dimensions");
            dims.push_back(parseDimension());
            skipSpace();
            trailingComma = false;
            if (peek() == ',') { ++pos_; trailingComma = true; continue; }
            expect(')', "expected ',' or ')' in shape");
            break;
        }
        // "(5)" is the integer 5 in Python, not a tuple; numpy never writes it.
        if (dims.size() == 1 && !trailingComma)
            bad(fmt::format("shape ({}) is not a tuple; a 1-d shape is written ({},)", dims[0], dims[0]));
        return dims;
    }

    std::string_view s_;
    const std::string& path_;
    size_t pos_ = 0;
};

struct FileCloser {
    void operator()(std::FILE* f) const { std::fclose(f); }
};

}  // namespace

size_t NpyArray::elementCount() const {
    size_t n = 1;
    for (uint64_t d : shape) n *= static_cast<size_t>(d);
    return n;
}

size_t NpyArray::itemSize() const {
    std::string why;
    auto d = parseDtype(dtype, why);
    return d ? d->size : 0;
}

std::string npyTypeName(std::string_view dtype) {
    std::string why;
    auto d = parseDtype(dtype, why);
    if (!d) return std::string(dtype);
    switch (d->kind) {
        case 'f': return fmt::format("float{}", d->size * 8);
        case 'i': return fmt::format("int{}", d->size * 8);
        case 'u': return fmt::format("uint{}", d->size * 8);
        default: return "bool";
    }
}

namespace {

/// Reads exactly @p n bytes or fails naming @p path and the part of the file (@p what).
void readFully(std::FILE* file, const std::string& path, void* dst, size_t n, const char* what) {
    if (n == 0) return;
    if (std::fread(dst, 1, n, file) != n) {
        if (std::ferror(file)) fail(path, "read failed: {}", errnoText(errno));
        fail(path, "file ends inside the {} (truncated .npy file?)", what);
    }
}

/// An open .npy file positioned at its data, with the validated header.
struct OpenedNpy {
    std::unique_ptr<std::FILE, FileCloser> file;
    NpyHeader header;
};

OpenedNpy openNpy(const std::string& path) {
    std::unique_ptr<std::FILE, FileCloser> file(openInputStream(path));
    struct stat st {};
    if (::fstat(::fileno(file.get()), &st) != 0) fail(path, "cannot stat: {}", errnoText(errno));
    const uint64_t fileBytes = static_cast<uint64_t>(st.st_size);

    auto readExact = [&](void* dst, size_t n, const char* what) { readFully(file.get(), path, dst, n, what); };

    // Magic and version.
    unsigned char prefix[8];
    if (fileBytes < sizeof prefix)
        fail(path, "too short to be a .npy file ({} bytes)", fileBytes);
    readExact(prefix, sizeof prefix, "magic string");
    if (std::memcmp(prefix, kMagic, kMagicBytes) != 0)
        fail(path, "not a .npy file (missing the \\x93NUMPY magic string)");
    const int major = prefix[6], minor = prefix[7];
    if ((major != 1 && major != 2 && major != 3) || minor != 0)
        fail(path, "unsupported .npy format version {}.{} (supported: 1.0, 2.0, 3.0)", major, minor);

    // Header length: 2 bytes in v1.0, 4 bytes from v2.0 on (both little endian).
    const size_t lenBytes = major == 1 ? 2 : 4;
    unsigned char lenRaw[4] = {0, 0, 0, 0};
    readExact(lenRaw, lenBytes, "header length");
    uint64_t headerLen = 0;
    for (size_t i = lenBytes; i-- > 0;) headerLen = (headerLen << 8) | lenRaw[i];
    const uint64_t dataOffset = sizeof prefix + lenBytes + headerLen;
    if (dataOffset > fileBytes)
        fail(path, "header length {} runs past the end of the file ({} bytes; truncated?)",
             headerLen, fileBytes);

    std::string header(static_cast<size_t>(headerLen), '\0');
    readExact(header.data(), header.size(), "header");
    HeaderParser::Result h = HeaderParser(header, path).parse();

    std::string why;
    auto dtype = parseDtype(h.descr, why);
    if (!dtype) fail(path, "{}", why);
    if (h.fortranOrder)
        fail(path, "array is stored in Fortran order; save it with np.ascontiguousarray() first");

    NpyHeader out;
    out.dtype = dtype->normalized;
    out.shape = std::move(h.shape);
    const auto expected = byteCount(out.shape, dtype->size);
    if (!expected || *expected > static_cast<uint64_t>(std::numeric_limits<size_t>::max()))
        fail(path, "header shape {} is too large", shapeText(out.shape));
    const uint64_t dataBytes = fileBytes - dataOffset;
    if (dataBytes != *expected)
        fail(path, "header says {} {} ({} bytes) but file has {} bytes of data", shapeText(out.shape),
             npyTypeName(out.dtype), *expected, dataBytes);
    out.dataBytes = dataBytes;
    return {std::move(file), std::move(out)};
}

}  // namespace

NpyRowReader::NpyRowReader(const std::string& path) : path_(path) {
    OpenedNpy opened = openNpy(path);
    header_ = std::move(opened.header);
    file_.reset(opened.file.release());
    if (!header_.shape.empty() && header_.shape[0] > 0) rowBytes_ = header_.dataBytes / header_.shape[0];
}

void NpyRowReader::read(void* dst, size_t bytes) { readFully(file_.get(), path_, dst, bytes, "data"); }

NpyArray readNpy(const std::string& path) {
    OpenedNpy opened = openNpy(path);
    std::FILE* file = opened.file.get();
    auto readExact = [&](void* dst, size_t n, const char* what) { readFully(file, path, dst, n, what); };
    NpyArray out;
    out.dtype = std::move(opened.header.dtype);
    out.shape = std::move(opened.header.shape);
    const uint64_t dataBytes = opened.header.dataBytes;

    out.data.resize(static_cast<size_t>(dataBytes));
    readExact(out.data.data(), out.data.size(), "data");
    return out;
}

std::vector<float> npyAsFloat32(const NpyArray& array, const std::string& path) {
    const size_t n = array.elementCount();
    std::vector<float> out(n);
    if (array.dtype == "<f4" && array.data.size() == n * sizeof(float)) {
        if (n) std::memcpy(out.data(), array.data.data(), n * sizeof(float));
    } else if (array.dtype == "<f8" && array.data.size() == n * sizeof(double)) {
        for (size_t i = 0; i < n; ++i) {
            double v;
            std::memcpy(&v, array.data.data() + i * sizeof(double), sizeof v);
            out[i] = static_cast<float>(v);
        }
    } else if (array.dtype == "<f4" || array.dtype == "<f8") {
        fail(path, "array holds {} bytes but its shape {} needs {}", array.data.size(),
             shapeText(array.shape), n * array.itemSize());
    } else {
        fail(path, "expected a float32 or float64 array but got {} ('{}')", npyTypeName(array.dtype),
             array.dtype);
    }
    return out;
}

void writeNpy(const std::string& path, std::string_view dtypeText, std::span<const uint64_t> shape,
              const void* data, size_t bytes) {
    std::string why;
    auto dtype = parseDtype(dtypeText, why);
    if (!dtype) fail(path, "cannot write .npy: {}", why);
    const auto expected = byteCount(shape, dtype->size);
    if (!expected || *expected != bytes)
        fail(path, "cannot write .npy: shape {} of {} needs {} bytes but {} were given",
             shapeText(shape), npyTypeName(dtype->normalized),
             expected ? fmt::format("{}", *expected) : std::string("too many"), bytes);

    // Exactly what numpy's format.write_array emits: a dict with sorted keys, a tuple shape
    // with a trailing comma for one dimension, then spaces up to the alignment and a newline.
    std::string shapeRepr;
    if (shape.size() == 1) shapeRepr = fmt::format("({},)", shape[0]);
    else shapeRepr = fmt::format("({})", fmt::join(shape, ", "));
    std::string header = fmt::format("{{'descr': '{}', 'fortran_order': False, 'shape': {}, }}",
                                     dtype->normalized, shapeRepr);

    int major = 1;
    size_t prefixBytes = 10;
    auto padded = [&] {
        size_t total = prefixBytes + header.size() + 1;
        return header.size() + 1 + (kHeaderAlign - total % kHeaderAlign) % kHeaderAlign;
    };
    if (padded() > 0xFFFF) {  // only reachable with absurdly many dimensions
        major = 2;
        prefixBytes = 12;
    }
    const size_t headerLen = padded();
    header.append(headerLen - header.size() - 1, ' ');
    header.push_back('\n');

    std::string prefix(kMagic, kMagicBytes);
    prefix.push_back(static_cast<char>(major));
    prefix.push_back('\0');
    for (size_t i = 0; i < (major == 1 ? 2u : 4u); ++i)
        prefix.push_back(static_cast<char>((headerLen >> (8 * i)) & 0xFF));

    AtomicFile file(path);
    file.write(prefix.data(), prefix.size());
    file.write(header.data(), header.size());
    if (bytes) file.write(data, bytes);
    file.commit();
}

void writeNpy(const std::string& path, const NpyArray& array) {
    writeNpy(path, array.dtype, array.shape, array.data.data(), array.data.size());
}

}  // namespace penumbra
