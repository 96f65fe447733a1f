#pragma once
/// @file PathText.h
/// @brief The one way a file name's extension is read: lower-cased, so that `.VDB`, `.Glb` and
/// `.OBJ` choose the same reader or writer as their lower-case spellings; and the one way two
/// output names are compared before anything exists.

#include <string>

namespace penumbra {

/// @brief The extension of @p path with its dot, lower-cased ("scene.GLB" -> ".glb"; "" if none).
std::string lowercaseExtension(const std::string& path);

/// @brief @p path absolute, with symbolic links resolved as far as it exists, and lexically
/// normal, without a trailing separator ("d/", "./d" and "l" with l -> d name what "d" names):
/// equal for two names of one output.
std::string comparablePath(const std::string& path);

}  // namespace penumbra
