#pragma once
/// @file Diagnostics.h
/// @brief Messages on stderr that can never change how a run ends.
///
/// A failing stderr (`2>/dev/full`, `2>&-`, a closed pipe) must not turn a successful bake into
/// an abort: fmt::print throws when its write fails, and a throw inside an error handler ends in
/// std::terminate. makeStandardStreamsSafe() therefore replaces `stderr` with a stream that
/// ignores write errors, points closed standard descriptors at /dev/null (so no output file is
/// ever opened as descriptor 2 and handed diagnostics), and ignores SIGPIPE, so that `| head`
/// ends a bake's messages, not the bake. Everything printed to `stderr` after the call (fmt,
/// stdio, progress lines) goes through the safe stream.

#include <string_view>

namespace penumbra {

/// @brief Makes stderr failure-proof as described above. Call once, first thing in main().
void makeStandardStreamsSafe();

/// @brief Writes @p text to stderr; never throws, whatever stderr is.
void printDiagnostic(std::string_view text) noexcept;

}  // namespace penumbra
