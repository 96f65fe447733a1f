// Tests for ProgressReporter, its line format and the timers.

#include "stream/util/Progress.h"

#include <catch2/catch.hpp>

#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <thread>
#include <vector>

using penumbra::formatDuration;
using penumbra::formatProgressLine;

TEST_CASE("formatProgressLine and formatDuration", "[io]") {
    CHECK(formatProgressLine("bake", 4200, 10000, 3.1, false) == "[bake] 42.0% (4200/10000) elapsed 3.1s ETA 4.3s");
    CHECK(formatProgressLine("bake", 0, 10000, 0.31, false) == "[bake] 0.0% (0/10000) elapsed 0.3s");
    CHECK(formatProgressLine("bake", 10000, 10000, 7.44, true) == "[bake] 100.0% (10000/10000) done in 7.4s");
    CHECK(formatProgressLine("bucket", 12, 0, 1.0, false) == "[bucket] 12 elapsed 1.0s");
    CHECK(formatProgressLine("write", 0, 0, 0.31, true) == "[write] done in 0.3s");  // a phase that counts nothing
    CHECK(formatProgressLine("x", 15, 10, 1.0, false) == "[x] 100.0% (15/10) elapsed 1.0s");
    CHECK(formatDuration(0.04) == "0.0s");
    CHECK(formatDuration(59.94) == "59.9s");
    CHECK(formatDuration(125) == "2m05s");
    CHECK(formatDuration(3720) == "1h02m");
    CHECK(formatDuration(-1) == "0.0s");
}

TEST_CASE("ProgressReporter counts work from many threads", "[io]") {
    penumbra::ProgressReporter progress("test", 40000, true);
    std::vector<std::thread> workers;
    for (int t = 0; t < 4; ++t)
        workers.emplace_back([&] {
            for (int i = 0; i < 10000; ++i) progress.update();
        });
    for (auto& w : workers) w.join();
    CHECK(progress.workDone() == 40000);
    progress.done();
    progress.done();  // idempotent
}

TEST_CASE("ProgressReporter writes short logs when stderr is not a terminal", "[io]") {
    char name[] = "/tmp/penumbra-progress-XXXXXX";
    int fd = ::mkstemp(name);
    REQUIRE(fd >= 0);
    std::fflush(stderr);
    int saved = ::dup(STDERR_FILENO);
    ::dup2(fd, STDERR_FILENO);
    {
        penumbra::ProgressReporter progress("phase", 10, false);
        for (int i = 0; i < 10; ++i) {
            progress.update();
            std::this_thread::sleep_for(std::chrono::milliseconds(30));
        }
    }  // the destructor prints the final line and joins the thread
    {
        penumbra::ProgressReporter quiet("silent", 10, true);
        quiet.update(10);
    }
    std::fflush(stderr);
    ::dup2(saved, STDERR_FILENO);
    ::close(saved);
    ::close(fd);

    std::ifstream in(name);
    std::stringstream text;
    text << in.rdbuf();
    ::unlink(name);
    // Under 2 s, the non-TTY mode prints only the final line, and the quiet reporter nothing.
    const std::string out = text.str();
    CHECK(out.rfind("[phase] 100.0% (10/10) done in ", 0) == 0);
    CHECK(std::count(out.begin(), out.end(), '\n') == 1);
    CHECK(out.find('\r') == std::string::npos);
}

TEST_CASE("Stopwatch and ScopedTimer measure wall time", "[io]") {
    penumbra::Stopwatch watch;
    double total = 0;
    {
        penumbra::ScopedTimer timer(total);
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        CHECK(timer.seconds() >= 0.019);
    }
    CHECK(total >= 0.019);
    CHECK(watch.seconds() >= total);
    watch.reset();
    CHECK(watch.seconds() < 0.019);
}
