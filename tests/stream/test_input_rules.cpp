// The input rules one unit at a time: paths that stay in their directory (SafePath), JSON depth
// and key-naming errors (JsonText), regular-file inputs and their identities (InputFile), and the
// overflow-checked products (CheckedMath).

#include "stream/util/CheckedMath.h"
#include "stream/util/InputFile.h"
#include "stream/util/JsonText.h"
#include "stream/util/SafePath.h"

#include "TestSupport.h"

#include <catch2/catch.hpp>

#include <sys/stat.h>

#include <filesystem>
#include <fstream>

using namespace penumbra;
using namespace penumbra::test;
namespace fs = std::filesystem;

TEST_CASE("percentDecode decodes as tinygltf does", "[stream][safe-path]") {
    CHECK(percentDecode("%2e%2E/a+b%20c") == "../a b c");
    CHECK(percentDecode("50%") == "50%");
    CHECK(percentDecode("%4") == "%4");
    CHECK(percentDecode("%zz") == std::string(1, '\0'));  // non-hex digits count as 0, like tinygltf's
}

TEST_CASE("containedPath keeps names inside their directory", "[stream][safe-path]") {
    ScratchDir dir;
    fs::create_directories(dir.path / "base/sub");
    const fs::path base = dir.path / "base";
    CHECK(containedPath(base, "mesh.obj", "w") == (base / "mesh.obj").string());
    CHECK(containedPath(base, "sub/../mesh.obj", "w") == (base / "mesh.obj").string());
    CHECK(containedPath(base, (base / "sub/x.obj").string(), "w") == (base / "sub/x.obj").string());
    CHECK(containedPath("", "x.obj", "w") == "x.obj");  // relative to the current directory, kept relative
    for (const std::string& bad : {std::string("../x.obj"), std::string("sub/../../x.obj"), std::string("/etc/passwd"),
                                   (dir.path / "x.obj").string()})
        CHECK_THROWS_WITH(containedPath(base, bad, "scene.json: geometry[0].path"),
                          Catch::StartsWith("scene.json: geometry[0].path: \"" + bad + "\" leaves the scene's directory"));
    CHECK_THROWS_WITH(containedPath(base, std::string("a\0b", 3), "w"), "w: the path contains a NUL byte");
    fs::create_symlink(dir.path, base / "up");
    CHECK_THROWS_WITH(containedPath(base, "up/x.obj", "w"), Catch::Contains("through a symbolic link"));
    AllowOutsidePaths allowed;
    CHECK(containedPath(base, "../x.obj", "w") == (dir.path / "x.obj").string());
}

TEST_CASE("JSON errors name the file, the key and the byte", "[stream][json]") {
    CHECK_THROWS_WITH(parseJsonText(R"({"a": {"b": [1, 2, 1e999]}})", "f.json"), "f.json: a.b[2]: number overflow parsing '1e999'");
    CHECK_THROWS_WITH(parseJsonText(R"({"a": [true, nul]})", "f.json"),
                      Catch::StartsWith("f.json: invalid JSON at byte 17 (in a[1]): "));
    CHECK_THROWS_WITH(parseJsonText(std::string(65, '[') + std::string(65, ']'), "f.json"),
                      "f.json: JSON nests deeper than 64 levels (at byte 64)");
    CHECK(parseJsonText(std::string(64, '[') + std::string(64, ']'), "f.json").is_array());
    CHECK(parseJsonText(R"({"s": "[[[{{{\"]]]"})", "f.json")["s"] == "[[[{{{\"]]]");
    // A key given twice is an error naming it (nlohmann keeps the last one silently); the same
    // key in two objects is not.
    CHECK_THROWS_WITH(parseJsonText(R"({"lights": [{"samples": 16, "u": 1, "samples": 64}]})", "f.json"),
                      "f.json: lights[0].samples: is given twice in one object (a key may appear once)");
    CHECK(parseJsonText(R"({"a": {"k": 1}, "b": {"k": 2}, "c": [{"k": 3}, {"k": 4}]})", "f.json")["c"][1]["k"] == 4);
}

TEST_CASE("inputs are regular files, recorded only inside a job", "[stream][input-file]") {
    ScratchDir dir;
    std::ofstream(dir / "a.txt") << "a";
    REQUIRE(::mkfifo((dir / "fifo").c_str(), 0600) == 0);
    CHECK_THROWS_WITH(checkInputFile(dir / "fifo"), dir / "fifo" + ": is a FIFO, not a regular file");
    CHECK_THROWS_WITH(checkInputFile(dir.path.string()), dir.path.string() + ": is a directory, not a regular file");
    CHECK_THROWS_WITH(checkInputFile(dir / "none"), dir / "none" + ": cannot open: No such file or directory");
    struct stat st {};
    REQUIRE(::stat((dir / "a.txt").c_str(), &st) == 0);
    checkInputFile(dir / "a.txt");
    CHECK_FALSE(recordedInput(st.st_dev, st.st_ino));  // no job: nothing is recorded
    {
        InputScope job;
        checkInputFile(dir / "a.txt");
        CHECK(recordedInput(st.st_dev, st.st_ino) == dir / "a.txt");
    }
    CHECK_FALSE(recordedInput(st.st_dev, st.st_ino));
}

TEST_CASE("checkedProduct refuses overflow and counts beyond the limit, naming the key", "[stream][checked-math]") {
    CHECK(checkedProduct({3, 4, 5}, 60, "k", "items") == 60);
    CHECK_THROWS_WITH(checkedProduct({3, 4, 5}, 59, "s.json: k", "items"),
                      "s.json: k: 3 x 4 x 5 = 60 items, more than the limit of 59");
    CHECK_THROWS_WITH(checkedProduct({uint64_t(1) << 32, uint64_t(1) << 32}, UINT64_MAX, "k", "pixels"),
                      "k: 4294967296 x 4294967296 pixels overflows 64 bits");
    CHECK_THROWS_WITH(checkedSum(UINT64_MAX, 1, UINT64_MAX, "k", "samples"), "k: 18446744073709551615 + 1 samples overflows 64 bits");
    const uint64_t shape[3] = {1u << 30, 1u << 30, 1u << 30};
    CHECK_FALSE(productOf(shape));
}
