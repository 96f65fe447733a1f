#pragma once
/// @file GltfPrecheck.h
/// @brief What a glTF or GLB file must pass before tinygltf parses it, kept apart from the reader
/// so that every glTF reader (GltfReader.h and whatever replaces it) calls the same check.
///
/// - Nesting: tinygltf parses `extras` and `extensions` recursively, so 20,000 nested arrays
///   overflow the stack; the JSON is limited to kMaxJsonDepth levels (JsonText.h) first.
/// - URIs: every buffer and image URI that names a file, percent-decoded as tinygltf decodes it,
///   must stay inside the model's directory (SafePath.h; `--allow-outside-uris` lifts this). A
///   file missing there must not exist in the current directory either, because tinygltf looks
///   for it there next. Buffer files are recorded as inputs (InputFile.h), so no output replaces
///   one.

#include <span>
#include <string>

namespace penumbra {

/// @brief Checks the whole file @p bytes of the glTF or GLB @p path (told apart by the magic).
/// A GLB whose container headers are inconsistent, or JSON that does not parse, is left to the
/// reader, which reports it.
/// @throw InputError "PATH: JSON nests deeper than 64 levels (at byte N)", or "PATH:
///        buffers[0].uri: "../secret.bin" leaves the model's directory DIR (...)".
void checkGltfBeforeParsing(const std::string& path, std::span<const unsigned char> bytes);

}  // namespace penumbra
