#include "stream/ObjTokenizer.h"

#include "stream/util/Error.h"

#include <cfloat>
#include <charconv>
#include <cmath>

namespace penumbra {
namespace {

/// from_chars does not accept a leading '+', which some exporters write ("+-1" stays invalid).
std::string_view withoutPlus(std::string_view token) {
    if (token.size() > 1 && token[0] == '+' && token[1] != '-' && token[1] != '+') token.remove_prefix(1);
    return token;
}

bool parseInteger(std::string_view token, int64_t& value) {
    token = withoutPlus(token);
    auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
    return error == std::errc() && end == token.data() + token.size() && !token.empty();
}

/// A 1-based (or negative, relative) index into @p count entries, zero-based. @p field is 0 for
/// the vertex, 1 for the texture coordinate, 2 for the normal.
int64_t resolve(int64_t index, uint64_t count, int field, const ObjLocation& where) {
    static const char* kIndex[3] = {"index", "texture coordinate index", "normal index"};
    static const char* kEntries[3] = {"vertices", "texture coordinates", "normals"};
    if (index == 0) fail(where.text(), "face {} 0 is invalid (OBJ indices start at 1)", kIndex[field]);
    const int64_t n = int64_t(count), resolved = index > 0 ? index - 1 : n + index;
    if (resolved < 0 || resolved >= n) fail(where.text(), "face {} {} out of range ({} {})", kIndex[field], index, count, kEntries[field]);
    return resolved;
}

constexpr const char* kSpace = " \t\v\f";

}  // namespace

std::string_view objLineText(std::string_view raw, uint64_t lineNumber) {
    while (!raw.empty() && (raw.back() == '\n' || raw.back() == '\r')) raw.remove_suffix(1);
    if (lineNumber == 1 && raw.starts_with("\xEF\xBB\xBF")) raw.remove_prefix(3);
    return raw;
}

std::string_view ObjTokens::next() {
    size_t begin = rest_.find_first_not_of(kSpace);
    if (begin == std::string_view::npos) return {};
    size_t end = rest_.find_first_of(kSpace, begin);
    if (end == std::string_view::npos) end = rest_.size();
    std::string_view token = rest_.substr(begin, end - begin);
    rest_.remove_prefix(end);
    return token;
}

std::string_view ObjTokens::rest() const {
    const size_t begin = rest_.find_first_not_of(kSpace);
    if (begin == std::string_view::npos) return {};
    const size_t end = rest_.find_last_not_of(kSpace);
    return rest_.substr(begin, end + 1 - begin);
}

namespace {

/// @p token as an error quotes it: cut after 32 characters, with its length (a 10 MB number was
/// quoted whole, up to the 9 KiB line cut).
std::string quotedToken(std::string_view token) {
    if (token.size() <= 40) return fmt::format("'{}'", token);
    return fmt::format("'{}...' ({} characters)", token.substr(0, 32), token.size());
}

}  // namespace

float parseObjNumber(std::string_view token, const ObjLocation& where) {
    std::string_view digits = withoutPlus(token);
    float value = 0;
    auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (end != digits.data() + digits.size() || (error != std::errc() && error != std::errc::result_out_of_range))
        fail(where.text(), "unparsable number {}", quotedToken(token));
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
        if (!(std::abs(wide) <= FLT_MAX))
            fail(where.text(), "coordinate {} is out of the float range (at most {:g} in magnitude)", quotedToken(token), double(FLT_MAX));
        value = std::copysign(static_cast<float>(wide), digits[0] == '-' ? -1.0f : 1.0f);
    }
    if (!std::isfinite(value)) fail(where.text(), "non-finite coordinate {}", quotedToken(token));
    return value;
}

glm::vec3 parseObjVector(ObjTokens& tokens, int count, const char* kind, const ObjLocation& where) {
    glm::vec3 p(0.0f);
    for (int axis = 0; axis < count; ++axis) {
        std::string_view token = tokens.next();
        if (token.empty()) fail(where.text(), "{} has {} coordinate{} (needs {})", kind, axis, axis == 1 ? "" : "s", count);
        p[axis] = parseObjNumber(token, where);
    }
    // A fourth value (w) or three more (vertex colour) are allowed but must be numbers.
    for (std::string_view extra = tokens.next(); !extra.empty(); extra = tokens.next()) parseObjNumber(extra, where);
    return p;
}

void parseObjFace(ObjTokens& tokens, const uint64_t counts[3], std::vector<ObjCorner>& corners, const ObjLocation& where) {
    corners.clear();
    for (std::string_view corner = tokens.next(); !corner.empty(); corner = tokens.next()) {
        if (corner == "\\" && tokens.next().empty())
            fail(where.text(), "ends in '\\': line continuations are not read; join the face's corners on one line");
        std::string_view fields[3];
        size_t fieldCount = 0;
        std::string_view rest = corner;
        while (true) {
            size_t slash = rest.find('/');
            if (fieldCount == 3) fail(where.text(), "unparsable face corner {}", quotedToken(corner));
            fields[fieldCount++] = rest.substr(0, slash);
            if (slash == std::string_view::npos) break;
            rest.remove_prefix(slash + 1);
        }
        ObjCorner c;
        int64_t* out[3] = {&c.v, &c.vt, &c.vn};
        for (size_t i = 0; i < fieldCount; ++i) {
            if (i > 0 && fields[i].empty()) continue;  // "v//vn"
            int64_t index = 0;
            if (!parseInteger(fields[i], index)) fail(where.text(), "unparsable face corner {}", quotedToken(corner));
            *out[i] = resolve(index, counts[i], int(i), where);
        }
        corners.push_back(c);
    }
    if (corners.size() < 3)
        fail(where.text(), "face has {} corner{} (needs at least 3)", corners.size(), corners.size() == 1 ? "" : "s");
}

}  // namespace penumbra
