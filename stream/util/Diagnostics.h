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

#include "stream/util/Error.h"

#include <fmt/format.h>

#include <string>
#include <string_view>

namespace penumbra {

/// @brief Makes stderr failure-proof as described above. Call once, first thing in main().
void makeStandardStreamsSafe();

/// @brief Writes @p text to stderr; never throws, whatever stderr is.
void printDiagnostic(std::string_view text) noexcept;

/// @brief Prints "penumbra: warning: MESSAGE" on stderr (never throws).
template <typename... Args>
void warning(fmt::format_string<Args...> format, Args&&... args) noexcept {
    try {
        printDiagnostic("penumbra: warning: " + printableLine(fmt::format(format, std::forward<Args>(args)...)) + "\n");
    } catch (...) {
    }
}

/// @brief Prints "penumbra: note: MESSAGE" on stderr unless @p quiet (never throws): for what a
/// user should know up front, such as a bake that will take hours.
template <typename... Args>
void notice(bool quiet, fmt::format_string<Args...> format, Args&&... args) noexcept {
    if (quiet) return;
    try {
        printDiagnostic("penumbra: note: " + printableLine(fmt::format(format, std::forward<Args>(args)...)) + "\n");
    } catch (...) {
    }
}

}  // namespace penumbra
