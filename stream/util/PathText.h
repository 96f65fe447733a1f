#pragma once
/// @file PathText.h
/// @brief The one way a file name's extension is read: lower-cased, so that `.VDB`, `.Glb` and
/// `.OBJ` choose the same reader or writer as their lower-case spellings.

#include <string>

namespace penumbra {

/// @brief The extension of @p path with its dot, lower-cased ("scene.GLB" -> ".glb"; "" if none).
std::string lowercaseExtension(const std::string& path);

}  // namespace penumbra
