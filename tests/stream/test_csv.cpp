// Tests for readCsvNumbers: headers, comments, line endings and error locations.

#include "stream/util/Csv.h"
#include "stream/util/Error.h"

#include "TestSupport.h"

#include <catch2/catch.hpp>

#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <functional>

using namespace penumbra::test;
namespace fs = std::filesystem;
using penumbra::InputError;
using penumbra::readCsvNumbers;
using Rows = std::vector<std::vector<double>>;

namespace {

/// A CSV file with the given content in its own scratch directory.
struct CsvFile {
    ScratchDir dir{"csv"};
    std::string path = dir.file("points.csv");
    explicit CsvFile(const std::string& content) { std::ofstream(path, std::ios::binary) << content; }
};

}  // namespace

TEST_CASE("readCsvNumbers reads plain numeric rows", "[io]") {
    CsvFile f("1,2,3\n4.5, -6e2 ,+7\n\n0.25,0,1e-3");  // no final newline
    CHECK(readCsvNumbers(f.path, 3) == Rows{{1, 2, 3}, {4.5, -600, 7}, {0.25, 0, 1e-3}});
}

TEST_CASE("readCsvNumbers skips a header, comments, blank lines, CRLF and a BOM", "[io]") {
    CsvFile f("\xEF\xBB\xBF# exported by tool\r\n\r\nx, y, z\r\n1,2,3\r\n  # comment\r\n   \r\n4,5,6\r\n");
    CHECK(readCsvNumbers(f.path, 3) == Rows{{1, 2, 3}, {4, 5, 6}});
}

TEST_CASE("readCsvNumbers with expectedColumns 0 takes the first row's width", "[io]") {
    CsvFile f("a,b\n1,2\n3,4\n");
    CHECK(readCsvNumbers(f.path, 0) == Rows{{1, 2}, {3, 4}});
    CsvFile g("1,2\n3,4,5\n");
    CHECK(errorOf([&] { readCsvNumbers(g.path, 0); }) == g.path + ":2: expected 2 columns but found 3");
}

TEST_CASE("readCsvNumbers refuses a first line of another width, which is data in another separator", "[io]") {
    // Taken as a header, it left a file of data rows in ';' silently empty.
    CsvFile semicolons("0;0;0\n1;2;3\n");
    CHECK(errorOf([&] { readCsvNumbers(semicolons.path, 3); }) ==
          semicolons.path + ":1: expected 3 comma-separated columns but found 1 (fields are separated by commas, not ';' or tabs)");
    CsvFile title("my points\n1,2,3\n");
    CHECK(errorOf([&] { readCsvNumbers(title.path, 3); }) == title.path + ":1: expected 3 comma-separated columns but found 1");
}

TEST_CASE("readCsvNumbers of an empty or header-only file gives no rows", "[io]") {
    CsvFile empty("");
    CHECK(readCsvNumbers(empty.path, 3).empty());
    CsvFile header("x,y,z\n# nothing yet\n");
    CHECK(readCsvNumbers(header.path, 3).empty());
}

TEST_CASE("readCsvNumbers reports file:line for bad rows", "[io]") {
    SECTION("wrong column count") {
        CsvFile f("x,y,z\n1,2,3\n4,5\n");
        CHECK(errorOf([&] { readCsvNumbers(f.path, 3); }) == f.path + ":3: expected 3 columns but found 2");
    }
    SECTION("bad field after the data started") {
        CsvFile f("1,2,3\n\n4,abc,6\n");
        CHECK(errorOf([&] { readCsvNumbers(f.path, 3); }) == f.path + ":3: field 2 'abc' is not a finite number");
    }
    SECTION("a second header is an error") {
        CsvFile f("x,y,z\nu,v,w\n");
        CHECK(errorOf([&] { readCsvNumbers(f.path, 3); }) == f.path + ":2: field 1 'u' is not a finite number");
    }
    SECTION("empty field") {
        CsvFile f("1,,3\n4,5,6\n");  // an empty field does not make the first line a header
        CHECK(errorOf([&] { readCsvNumbers(f.path, 3); }) == f.path + ":1: field 2 is empty");
        CsvFile g("1,2,3\n4,,6\n");
        CHECK(errorOf([&] { readCsvNumbers(g.path, 3); }) == g.path + ":2: field 2 is empty");
    }
    SECTION("a first row with numbers in it is data, whatever else it holds") {
        // Taken for a header, its receiver was dropped and the outputs were one row short.
        CsvFile typo("0,0,0,0,1,0O\n1,2,3,4,5,6\n");
        CHECK(errorOf([&] { readCsvNumbers(typo.path, 6); }) == typo.path + ":1: field 6 '0O' is not a finite number");
        CsvFile hex("0x10,0,0\n");
        CHECK(errorOf([&] { readCsvNumbers(hex.path, 3); }) == hex.path + ":1: field 1 '0x10' is not a finite number");
    }
    SECTION("non-finite values") {
        CsvFile e("nan,0,0\n1,2,3\n");  // not a header either
        CHECK(errorOf([&] { readCsvNumbers(e.path, 3); }) == e.path + ":1: field 1 'nan' is not a finite number");
        CsvFile f("1,2,3\nnan,0,0\n");
        CHECK(errorOf([&] { readCsvNumbers(f.path, 3); }) == f.path + ":2: field 1 'nan' is not a finite number");
        CsvFile g("1,2,3\n1,inf,0\n");
        CHECK(errorOf([&] { readCsvNumbers(g.path, 3); }) == g.path + ":2: field 2 'inf' is not a finite number");
        CsvFile h("1,2,3\n1,2,1e999\n");
        CHECK(errorOf([&] { readCsvNumbers(h.path, 3); }) == h.path + ":2: field 3 '1e999' is not a finite number");
    }
    SECTION("long garbage is quoted briefly") {
        CsvFile f("1\n" + std::string(500, 'z') + "\n");
        std::string msg = errorOf([&] { readCsvNumbers(f.path, 1); });
        CHECK(msg == f.path + ":2: field 1 '" + std::string(40, 'z') + "...' is not a finite number");
    }
}

TEST_CASE("readCsvNumbers names an unreadable file", "[io]") {
    CsvFile f("1\n");
    CHECK(errorOf([&] { readCsvNumbers(f.path + ".missing", 1); }) ==
          f.path + ".missing: cannot open: No such file or directory");
    CHECK(errorOf([&] { readCsvNumbers(f.dir.path.string(), 1); }) == f.dir.path.string() + ": is a directory, not a regular file");
}
