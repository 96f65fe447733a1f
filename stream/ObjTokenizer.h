#pragma once
/// @file ObjTokenizer.h
/// @brief The one reading of Wavefront OBJ statements, shared by the streaming blocker reader
/// (ObjReader.h) and the receiver meshes (IndexedMesh.h), so that one file gives the same
/// coordinates, bit for bit, and the same errors in both.
///
/// - A line is split at spaces and tabs; a `#` ends it (a comment, also after a statement).
/// - Numbers are parsed once, straight from decimal to float with std::from_chars (never through
///   double, which would round twice), so a float printed in shortest round-trip form reads back
///   with the same bits. A leading `+` is accepted (`v +1 0 0`); anything else that is not a
///   whole number is an error, in `v`, `vt` and `vn` alike (`vt x 0` is rejected by both readers).
/// - Face corners are `v`, `v/vt`, `v//vn` or `v/vt/vn`, with 1-based or negative (relative)
///   indices into the entries defined above the face.
/// - `o NAME` and `g NAME` start a part: the faces up to the next `o` or `g` belong to it.

#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include <glm/vec3.hpp>

namespace penumbra {

/// Where a statement is, for messages ("file.obj:12"), built only when one is needed.
struct ObjLocation {
    const std::string& path;
    uint64_t line = 0;
    std::string text() const { return path + ":" + std::to_string(line); }
};

/// @brief An OBJ line as its statements see it: without its line end ("\n", "\r\n", more "\r"s)
/// and, on line 1, without a UTF-8 byte order mark, which Windows tools write (kept, it made the
/// first vertex an unknown statement, and every face index then pointed one vertex later).
/// A "\r" anywhere else is not whitespace: `1.7\r960` is an unparsable number, not two.
std::string_view objLineText(std::string_view raw, uint64_t lineNumber);

/// @brief The parts of an OBJ as the receiver meshes and `convert` group them: part 0 holds the
/// faces before any `o` or `g`; every other name (the empty one of a bare `g` too) is one part,
/// however often it comes back. A hash, so that a file of a million groups is not quadratic.
class ObjGroupIndex {
public:
    /// @brief The part named @p name, added at the end when new; @return its index.
    size_t select(std::string_view name) {
        const auto [it, added] = index_.emplace(std::string(name), count_);
        count_ += added;
        return it->second;
    }
    /// Parts so far, part 0 included.
    size_t size() const { return count_; }

private:
    std::unordered_map<std::string, size_t> index_;
    size_t count_ = 1;
};

/// Splits a line into whitespace-separated tokens (spaces, tabs, \v, \f), stopping at a '#' comment.
class ObjTokens {
public:
    explicit ObjTokens(std::string_view line) : rest_(line.substr(0, line.find('#'))) {}

    /// @brief The next token, or an empty view when the line is used up.
    std::string_view next();
    /// @brief Everything not read yet, without surrounding whitespace (a part's name).
    std::string_view rest() const;

private:
    std::string_view rest_;
};

/// @brief Parses one coordinate. @p where ("file.obj:12") starts every message.
/// @throw InputError "WHERE: unparsable number 'TOKEN'" or "WHERE: non-finite coordinate 'TOKEN'".
float parseObjNumber(std::string_view token, const ObjLocation& where);

/// @brief Parses @p count coordinates from @p tokens (`v`, `vn`: 3; `vt`: 2), then checks that
/// whatever follows is numbers too (`v x y z w`, vertex colours, `vt u v w`).
/// @throw InputError "WHERE: KIND has N coordinates (needs COUNT)" or a number error.
glm::vec3 parseObjVector(ObjTokens& tokens, int count, const char* kind, const ObjLocation& where);

/// One face corner: zero-based indices, -1 when the corner has no vt (vn).
struct ObjCorner {
    int64_t v = -1, vt = -1, vn = -1;
};

/// @brief Parses the corners of an `f` statement.
/// @param counts the v, vt and vn entries defined above the face: the ranges indices address.
/// @throw InputError naming the corner: unparsable, index 0, out of range, fewer than 3 corners.
void parseObjFace(ObjTokens& tokens, const uint64_t counts[3], std::vector<ObjCorner>& corners, const ObjLocation& where);

}  // namespace penumbra
