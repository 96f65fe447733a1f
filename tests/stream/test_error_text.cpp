// Tests for printableLine and InputError: an error quoting a damaged file's bytes stays one
// printable line.

#include "stream/util/Error.h"

#include <catch2/catch.hpp>
#include <fmt/format.h>

#include <string>

using penumbra::InputError;
using penumbra::kMaxPrintableLine;
using penumbra::printableLine;

TEST_CASE("printableLine escapes control bytes and broken UTF-8, and keeps the rest", "[stream][errors]") {
    CHECK(printableLine("plain ASCII: 'x' (1..2)") == "plain ASCII: 'x' (1..2)");
    CHECK(printableLine("a\nb\rc\td\x1b[31me\x7f") == "a\\x0ab\\x0dc\\x09d\\x1b[31me\\x7f");
    CHECK(printableLine(std::string("nul\0end", 7)) == "nul\\x00end");
    // Well-formed UTF-8 of every length stays as it is (file names in any language).
    CHECK(printableLine("caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x8c\xbf") == "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x8c\xbf");
    // A stray continuation byte, an overlong form, a surrogate, a code point past U+10FFFF, and
    // sequences cut short, at the end or by another byte: each bad byte escaped on its own.
    CHECK(printableLine("\x80") == "\\x80");
    CHECK(printableLine("\xc0\x80") == "\\xc0\\x80");
    CHECK(printableLine("\xed\xa0\x80") == "\\xed\\xa0\\x80");
    CHECK(printableLine("\xf4\x90\x80\x80") == "\\xf4\\x90\\x80\\x80");
    CHECK(printableLine("\xe2\x82") == "\\xe2\\x82");
    CHECK(printableLine("\xc3" "A") == "\\xc3A");
    // Already printable text is left alone, so escaping twice changes nothing.
    const std::string once = printableLine("bad \xff\n");
    CHECK(printableLine(once) == once);
}

TEST_CASE("printableLine cuts a line of megabytes and says how much it left out", "[stream][errors]") {
    // OpenVDB quoted 16 MB of a damaged file's bytes in one message.
    const std::string huge = "KeyError: Map " + std::string(size_t(1) << 24, ' ') + " is not registered";
    const std::string line = printableLine(huge);
    CHECK(line.size() < kMaxPrintableLine + 64);
    CHECK_THAT(line, Catch::StartsWith("KeyError: Map ") && Catch::EndsWith(fmt::format("... ({} more bytes)", huge.size() - kMaxPrintableLine)));
    CHECK(printableLine(line) == line);  // a cut line passes through again unchanged
    // Escapes count towards the length, and the cut never splits one.
    const std::string escaped = printableLine(std::string(4000, '\x01'));
    CHECK(escaped.size() < kMaxPrintableLine + 64);
    CHECK_THAT(escaped, Catch::StartsWith("\\x01\\x01") && Catch::Contains("\\x01... ("));
    CHECK(printableLine(escaped) == escaped);
    // Lines near the limit are whole.
    const std::string near(kMaxPrintableLine + 40, 'a');
    CHECK(printableLine(near) == near);
}

TEST_CASE("InputError's message is one printable line", "[stream][errors]") {
    try {
        penumbra::fail("m.obj:3", "unparsable number '{}'", std::string("1\r2\xfe"));
        FAIL("fail() returned");
    } catch (const InputError& e) {
        CHECK(std::string(e.what()) == "m.obj:3: unparsable number '1\\x0d2\\xfe'");
    }
}
