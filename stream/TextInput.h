#pragma once
/// @file TextInput.h
/// @brief What counts as the text of a text input (OBJ, CSV), decided in one place for every
/// reader of one.
///
/// - A binary file (a NUL byte, or a UTF-16 byte order mark, in its first 64 KiB: an EXR, a
///   PNG, random bytes, UTF-16 text) is not an OBJ file; it would otherwise read as 0 triangles.
/// - A line read that fails is an error, not the end of the file: getline() returns -1 both at
///   the end and when it cannot grow its buffer for a long line (ENOMEM), and in the second case
///   it sets no error flag, so only feof() tells them apart. Truncating silently would bake a
///   part of the mesh.
/// - A non-empty file in which no face line was understood gets a warning.

#include <cstdint>
#include <cstdio>
#include <string>

namespace penumbra {

/// @brief Refuses a file whose start is not text.
/// @param format names the format in messages: "OBJ".
/// @throw InputError "PATH: is binary, not OBJ text (a NUL byte at offset 12)" or "PATH: is
///        UTF-16 text; OBJ files are ASCII or UTF-8".
void checkTextFile(const std::string& path, const char* format);

/// @brief For a reader's line loop, once getline() has returned -1: returns at the end of the
/// file, and throws otherwise.
/// @param readErrno errno as getline() left it.
/// @throw InputError "WHERE: read error: Cannot allocate memory".
void checkLineReadEnded(std::FILE* file, const std::string& where, int readErrno);

/// @brief Warns on stderr when the non-empty OBJ @p path gave no triangle.
void warnIfNoFaces(const std::string& path, uint64_t triangles);

}  // namespace penumbra
