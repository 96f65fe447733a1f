#pragma once
/// @file JsonText.h
/// @brief JSON text from untrusted files: the nesting depth is limited before anything recursive
/// sees the text, and every exception the JSON library throws becomes an InputError naming the
/// file, the key and the byte.
///
/// Why a depth limit: parsers, tree walks, copies, dumps and destructors of a JSON document
/// recurse once per level of nesting (nlohmann's copy and dump, tinygltf's `extras`), so a file
/// of 10,000 nested arrays overflows the stack. The text is scanned first, iteratively, and a
/// document that nests deeper than kMaxJsonDepth arrays and objects is refused; every later
/// recursion is then bounded by that depth.

#include <nlohmann/json.hpp>

#include <string>
#include <string_view>

namespace penumbra {

/// Deepest nesting of arrays and objects accepted in any JSON input (scene files, glTF).
inline constexpr int kMaxJsonDepth = 64;

/// @brief Scans @p text (no parsing) and refuses arrays and objects nested deeper than @p limit.
/// Brackets inside strings do not count. Malformed text is left to the parser.
/// @throw InputError "WHERE: JSON nests deeper than 64 levels (at byte 4096)".
void checkJsonDepth(std::string_view text, const std::string& where, int limit = kMaxJsonDepth);

/// @brief Parses @p text after checkJsonDepth(). Library errors become InputErrors naming the key
/// being read: "scene.json: lights[0].power: number overflow parsing '1e309' (byte 212)".
/// @throw InputError naming @p where for any failure.
nlohmann::json parseJsonText(std::string_view text, const std::string& where);

}  // namespace penumbra
