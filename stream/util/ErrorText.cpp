#include "stream/util/Error.h"

#include <algorithm>
#include <cstdint>

namespace penumbra {
namespace {

/// The length of the well-formed UTF-8 sequence at @p s[i] (1-4), or 0 when the byte there does
/// not start one (a stray continuation byte, an overlong or surrogate form, a cut sequence).
size_t utf8Length(std::string_view s, size_t i) {
    const auto byte = [&](size_t k) { return k < s.size() ? uint8_t(s[k]) : uint8_t(0); };
    const uint8_t b0 = byte(i);
    auto continuation = [&](size_t k, uint8_t lo = 0x80, uint8_t hi = 0xBF) { return byte(k) >= lo && byte(k) <= hi; };
    if (b0 >= 0xC2 && b0 <= 0xDF) return continuation(i + 1) ? 2 : 0;
    if (b0 >= 0xE0 && b0 <= 0xEF) {
        const uint8_t lo = b0 == 0xE0 ? 0xA0 : 0x80, hi = b0 == 0xED ? 0x9F : 0xBF;
        return continuation(i + 1, lo, hi) && continuation(i + 2) ? 3 : 0;
    }
    if (b0 >= 0xF0 && b0 <= 0xF4) {
        const uint8_t lo = b0 == 0xF0 ? 0x90 : 0x80, hi = b0 == 0xF4 ? 0x8F : 0xBF;
        return continuation(i + 1, lo, hi) && continuation(i + 2) && continuation(i + 3) ? 4 : 0;
    }
    return 0;
}

}  // namespace

std::string printableLine(std::string_view text) {
    std::string out;
    out.reserve(std::min(text.size(), kMaxPrintableLine + 32));
    for (size_t i = 0; i < text.size();) {
        // Cut between characters, never inside one; a short rest (the note of an earlier cut)
        // is kept, so that a cut line passes through again unchanged.
        if (out.size() >= kMaxPrintableLine && text.size() - i > 64) {
            out += fmt::format("... ({} more bytes)", text.size() - i);
            break;
        }
        const uint8_t b = uint8_t(text[i]);
        if (b >= 0x20 && b < 0x7F) {
            out += char(b), ++i;
        } else if (const size_t n = b >= 0x80 ? utf8Length(text, i) : 0) {
            out.append(text.substr(i, n)), i += n;  // a file name in any language stays readable
        } else {
            out += fmt::format("\\x{:02x}", b), ++i;  // a control byte or broken UTF-8 from the input
        }
    }
    return out;
}

}  // namespace penumbra
