#pragma once
/// @file SafePath.h
/// @brief Paths that an untrusted file names stay inside that file's directory: a scene's
/// geometry, points and output paths (relative to the scene file), a glTF's buffer and image
/// URIs (relative to the model). Otherwise `penumbra convert model.gltf out.obj` with a buffer
/// URI of `../../home/me/.ssh/id_rsa` would copy any readable file into the output, and a
/// downloaded scene could overwrite any writable one. `--allow-outside-uris` lifts the rule for
/// the whole process (setOutsidePathsAllowed()).
///
/// A name leaves the directory when, after percent-decoding (for URIs), it is absolute and
/// outside it, climbs out with "..", or reaches outside through a symbolic link on the way
/// (checked on the path's existing part). Names with a NUL byte are refused outright.

#include <filesystem>
#include <string>
#include <string_view>

namespace penumbra {

/// @brief Lets every path leave its directory (`--allow-outside-uris`), or restores the rule.
void setOutsidePathsAllowed(bool allowed);
/// True after setOutsidePathsAllowed(true).
bool outsidePathsAllowed();

/// @brief Percent-decodes a URI exactly as tinygltf does before it opens the file ("%2e" is
/// '.', '+' is a space, a '%' without two following characters stays), so the check sees the
/// name tinygltf will open.
std::string percentDecode(std::string_view uri);

/// @brief True when @p inner is @p outer or lies below it (both absolute and lexically normal).
bool isInside(const std::filesystem::path& inner, const std::filesystem::path& outer);

/// @brief Resolves @p name against @p baseDir and refuses it if it leaves @p baseDir.
/// @param what names the directory in messages: "the scene's directory", "the model's directory".
/// @return the resolved, lexically normal path (relative when @p baseDir is).
/// @throw InputError "WHERE: "../x.obj" leaves the scene's directory DIR (--allow-outside-uris
///        allows it)".
std::string containedPath(const std::filesystem::path& baseDir, const std::string& name, const std::string& where,
                          const char* what = "the scene's directory");

}  // namespace penumbra
