#pragma once
/// @file OptionForms.h
/// @brief CLI11 checks of an option's form, so that a malformed value is a usage error (exit 2,
/// with the parser's message and the --help to read) like `--threads x`, while a value of the
/// right form that is refused (`--memory-budget 0`, `--shard 5/3`) stays an input error (exit 1).

#include "stream/util/Error.h"
#include "stream/util/Memory.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cctype>
#include <string>
#include <string_view>

namespace penumbra {

/// Whether @p text is two decimal numbers around one @p separator (`0/4`, `0-3`).
inline bool numbersAround(const std::string& text, char separator) {
    const size_t at = text.find(separator);
    auto digits = [](std::string_view s) {
        return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); });
    };
    return at != std::string::npos && digits(std::string_view(text).substr(0, at)) && digits(std::string_view(text).substr(at + 1));
}

/// @brief A byte size as parseByteSize() reads it (`256M`, `2G`, `1.5GiB`).
inline CLI::Validator byteSizeForm() {
    return CLI::Validator(
        [](std::string& text) -> std::string {
            const std::string prefix = "value: ";
            try {
                (void)parseByteSize(text, "value");
                return "";
            } catch (const InputError& e) {
                const std::string message = e.what();
                return message.starts_with(prefix) ? message.substr(prefix.size()) : message;
            }
        },
        "SIZE");
}

/// @brief `I/N` with decimal numbers, or `slurm`.
inline CLI::Validator shardForm() {
    return CLI::Validator(
        [](std::string& text) -> std::string {
            if (text == "slurm") return "";
            if (numbersAround(text, '/')) return "";
            return "'" + text + "' is not I/N (shard I of N, e.g. 0/4) or slurm";
        },
        "I/N");
}

/// @brief `A-B` with decimal numbers (a range of shards); the numbers' own limits are the
/// command's to check (exit 1).
inline CLI::Validator shardRangeForm() {
    return CLI::Validator(
        [](std::string& text) -> std::string {
            if (numbersAround(text, '-')) return "";
            return "'" + text + "' is not A-B (shards A to B, e.g. 0-3)";
        },
        "A-B");
}

/// @brief Refuses a value of the right form outside [@p lo, @p hi] (NaN included) as an input
/// error naming @p option (exit 1); a CLI::Range check would make it a usage error (exit 2).
/// @throw InputError "OPTION: must be in LO..HI, got VALUE".
template <class T>
void requireInRange(const char* option, T value, T lo, T hi) {
    if (!(value >= lo && value <= hi)) fail(option, "must be in {}..{}, got {}", lo, hi, value);
}

}  // namespace penumbra
