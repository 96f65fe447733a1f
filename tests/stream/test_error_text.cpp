// Tests for printableLine and InputError: an error quoting a damaged file's bytes stays one
// printable line.

#include "stream/util/Error.h"

#include <catch2/catch.hpp>

#include <string>

using penumbra::InputError;
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

TEST_CASE("InputError's message is one printable line", "[stream][errors]") {
    try {
        penumbra::fail("m.obj:3", "unparsable number '{}'", std::string("1\r2\xfe"));
        FAIL("fail() returned");
    } catch (const InputError& e) {
        CHECK(std::string(e.what()) == "m.obj:3: unparsable number '1\\x0d2\\xfe'");
    }
}
