#pragma once
/// @file Error.h
/// @brief The one exception type user-facing errors travel in.
///
/// Every error a user can cause (a malformed file, a bad scene key, a full disk) is thrown as
/// InputError whose what() is a single line naming the file or key and what is wrong with it.
/// The CLI prints it after "penumbra: error: " and exits non-zero; nothing else catches it.

#include <fmt/format.h>

#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>

namespace penumbra {

/// @brief @p text as one printable line: control bytes (a line break, a carriage return, an
/// escape sequence) and bytes that are not well-formed UTF-8 become `\xNN`; printable ASCII and
/// well-formed UTF-8 (file names) are kept. Messages quote tokens from the input, and a damaged
/// file's token must neither break the error's one line nor write raw bytes to a terminal.
/// A line longer than kMaxPrintableLine bytes is cut there and says how much was left out (a
/// library's message can quote megabytes of a damaged file). Two paths of PATH_MAX (4096) and
/// the reason after them fit: at 1 KiB, "does not exist (create it first)" was cut from a
/// message quoting an 800-character path twice.
std::string printableLine(std::string_view text);
inline constexpr size_t kMaxPrintableLine = 9216;

class InputError : public std::runtime_error {
public:
    /// @param message one line; any byte printableLine() would escape is escaped here.
    explicit InputError(const std::string& message) : std::runtime_error(printableLine(message)) {}
};

/// @brief Throws InputError("WHERE: MESSAGE"), formatting MESSAGE with fmt.
template <typename... Args>
[[noreturn]] void fail(const std::string& where, fmt::format_string<Args...> format, Args&&... args) {
    throw InputError(where + ": " + fmt::format(format, std::forward<Args>(args)...));
}

/// @brief Prints "penumbra: note: MESSAGE" on stderr. A diagnostic must never change how a bake
/// ends, so a failing stderr is ignored.
template <typename... Args>
void printNote(fmt::format_string<Args...> format, Args&&... args) noexcept {
    try {
        fmt::print(stderr, "penumbra: note: {}\n", printableLine(fmt::format(format, std::forward<Args>(args)...)));
    } catch (...) {
    }
}

/// @brief Prints "penumbra: warning: MESSAGE" on stderr: something in the input that almost
/// certainly is not what was meant (a light facing away from every receiver). Warnings print
/// even under --quiet, which silences progress and notes only; a failing stderr is ignored.
template <typename... Args>
void printWarning(fmt::format_string<Args...> format, Args&&... args) noexcept {
    try {
        fmt::print(stderr, "penumbra: warning: {}\n", printableLine(fmt::format(format, std::forward<Args>(args)...)));
    } catch (...) {
    }
}

/// @brief The text of errno value @p err ("No space left on device"); thread-safe, unlike strerror.
inline std::string errnoText(int err) { return std::error_code(err, std::generic_category()).message(); }

}  // namespace penumbra
