// ProgressSource: one display per pass over a source, a "done" line only for a pass read to its end.

#include "stream/ProgressSource.h"

#include <catch2/catch.hpp>

#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <vector>

using namespace penumbra;

namespace {

std::unique_ptr<VectorSource> tenTriangles() {
    std::vector<Triangle> triangles(10);
    for (size_t i = 0; i < triangles.size(); ++i) triangles[i].v = {glm::vec3(float(i), 0, 0), glm::vec3(float(i), 1, 0), glm::vec3(float(i) + 1, 0, 0)};
    return std::make_unique<VectorSource>(std::move(triangles), "ten");
}

/// What @p f writes to stderr.
template <class F>
std::string stderrOf(F&& f) {
    char name[] = "/tmp/penumbra-progress-source-XXXXXX";
    const int fd = ::mkstemp(name);
    REQUIRE(fd >= 0);
    std::fflush(stderr);
    const int saved = ::dup(STDERR_FILENO);
    ::dup2(fd, STDERR_FILENO);
    f();
    std::fflush(stderr);
    ::dup2(saved, STDERR_FILENO);
    ::close(saved);
    ::close(fd);
    std::stringstream text;
    text << std::ifstream(name).rdbuf();
    ::unlink(name);
    return text.str();
}

}  // namespace

TEST_CASE("ProgressSource shows each pass that is read to its end, and passes the triangles on unchanged", "[io][progress]") {
    std::vector<Triangle> seen;
    const std::string out = stderrOf([&] {
        ProgressSource source(tenTriangles(), "read ten", false);
        std::vector<Triangle> chunk(4);
        while (const size_t n = source.read(chunk)) seen.insert(seen.end(), chunk.begin(), chunk.begin() + ptrdiff_t(n));
        CHECK(source.read(chunk) == 0);  // past the end: no second display
        source.rewind();                 // a second pass, left after one read: no "done" line
        CHECK(source.read(chunk) == 4);
        CHECK(currentProgress().has_value());
        CHECK(currentProgress()->phase == "read ten");
        CHECK(currentProgress()->done == 4);
        CHECK(currentProgress()->total == 10);
    });
    CHECK(!currentProgress().has_value());  // the unfinished pass ended with its source
    REQUIRE(seen.size() == 10);
    const std::vector<Triangle> expected = [] {
        std::vector<Triangle> all(10);
        tenTriangles()->read(all);
        return all;
    }();
    for (size_t i = 0; i < seen.size(); ++i) CHECK(seen[i].v == expected[i].v);
    CHECK(out.rfind("[read ten] 100.0% (10/10) done in ", 0) == 0);
    CHECK(std::count(out.begin(), out.end(), '\n') == 1);
}

TEST_CASE("a quiet ProgressSource prints nothing but feeds currentProgress()", "[io][progress]") {
    const std::string out = stderrOf([] {
        ProgressSource source(tenTriangles(), "quiet", true);
        std::vector<Triangle> chunk(3);
        CHECK(source.read(chunk) == 3);
        REQUIRE(currentProgress().has_value());
        CHECK(currentProgress()->done == 3);
        while (source.read(chunk)) {
        }
        CHECK(!currentProgress().has_value());
    });
    CHECK(out.empty());
}
