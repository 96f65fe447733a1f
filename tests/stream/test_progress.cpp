// Tests for ProgressReporter, its line format and the timers.

#include "stream/util/Progress.h"
#include "stream/util/ProgressEstimate.h"

#include <catch2/catch.hpp>

#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <cmath>
#include <algorithm>
#include <cstdio>
#include <optional>
#include <fstream>
#include <functional>
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

namespace {

/// What @p body writes to stderr, redirected to a file (not a terminal) while it runs.
std::string capturedStderr(const std::function<void()>& body) {
    char name[] = "/tmp/penumbra-progress-XXXXXX";
    int fd = ::mkstemp(name);
    REQUIRE(fd >= 0);
    std::fflush(stderr);
    int saved = ::dup(STDERR_FILENO);
    ::dup2(fd, STDERR_FILENO);
    body();
    std::fflush(stderr);
    ::dup2(saved, STDERR_FILENO);
    ::close(saved);
    ::close(fd);
    std::ifstream in(name);
    std::stringstream text;
    text << in.rdbuf();
    ::unlink(name);
    return text.str();
}

}  // namespace

TEST_CASE("ProgressReporter writes short logs when stderr is not a terminal", "[io]") {
    const std::string out = capturedStderr([] {
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
        {
            penumbra::ProgressReporter outgrown("outgrown", 10, false);  // the estimate was short
            outgrown.update(12);
        }
    });
    // Under 2 s, the non-TTY mode prints only the final line, and the quiet reporter nothing.
    CHECK(out.rfind("[phase] 100.0% (10/10) done in ", 0) == 0);
    CHECK(out.find("[outgrown] 100.0% (12/12) done in ") != std::string::npos);
    CHECK(std::count(out.begin(), out.end(), '\n') == 2);
    CHECK(out.find('\r') == std::string::npos);
}

TEST_CASE("ProgressReporter: paused time counts neither in the elapsed time nor in the rate", "[io][progress]") {
    penumbra::ProgressReporter progress("cast", 100, true);
    progress.update(10);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const double before = progress.elapsedSeconds();
    progress.pause();
    progress.pause();  // twice is once
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    CHECK(progress.elapsedSeconds() - before < 0.15);  // frozen while paused
    {
        penumbra::ProgressReporter nested("shade", 5, true);  // the phase that runs meanwhile
        nested.update(5);
        CHECK(penumbra::currentProgress()->phase == "shade");
    }
    progress.resume();
    progress.resume();
    CHECK(penumbra::currentProgress()->phase == "cast");
    const double after = progress.elapsedSeconds();
    CHECK(after >= before);
    CHECK(after - before < 0.15);
    CHECK(progress.elapsedSeconds() < 0.2);  // the 0.3 s paused are not in it
    // The ETA comes from the unpaused time alone: 10 items in about 20 ms, 90 left, well under the
    // 2.7 s that the paused 0.3 s would have made it.
    const penumbra::ProgressSnapshot s = progress.snapshot();
    REQUIRE(s.remainingSeconds);
    CHECK(*s.remainingSeconds < 1.5);
}

TEST_CASE("ProgressReporter: a paused line stays above the nested phase's on a terminal", "[io][progress]") {
    // A pseudo-terminal would be needed to see the redraws; a file shows that nothing is printed
    // while paused and the closing line after it.
    const std::string out = capturedStderr([] {
        penumbra::ProgressReporter cast("cast", 10, false);
        cast.update(5);
        cast.pause();
        {
            penumbra::ProgressReporter shade("shade", 3, false);
            shade.update(3);
        }
        cast.resume();
        cast.update(5);
    });
    CHECK(out.rfind("[shade] 100.0% (3/3) done in ", 0) == 0);
    CHECK(out.find("\n[cast] 100.0% (10/10) done in ") != std::string::npos);
    CHECK(std::count(out.begin(), out.end(), '\n') == 2);
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

namespace {

/// A synthetic cast: @p items items in chunks of @p chunk, item i costing cost(i) units of work,
/// one unit a microsecond. Samples every 0.25 s as the display does, and returns what the
/// estimate said at each sample with the true remaining time.
struct EstimatePoint {
    double seconds, fraction, remaining;
    std::optional<double> eta;
};
template <class Cost>
std::vector<EstimatePoint> runSchedule(uint64_t items, uint64_t chunk, Cost cost) {
    std::vector<double> finished;  // time at which each chunk is finished
    std::vector<uint64_t> workAt;  // work at that time
    double t = 0;
    uint64_t work = 0;
    for (uint64_t i = 0; i < items; ++i) {
        work += cost(i);
        t = double(work) * 1e-6;
        if ((i + 1) % chunk == 0 || i + 1 == items) finished.push_back(t), workAt.push_back(work);
    }
    const double end = t;
    penumbra::WorkEstimate estimate(items);
    std::vector<EstimatePoint> out;
    for (double s = 0.25; s < end; s += 0.25) {
        size_t c = 0;
        while (c < finished.size() && finished[c] <= s) ++c;
        const uint64_t done = std::min<uint64_t>(items, c * chunk);
        estimate.sample(s, done, uint64_t(s * 1e6));  // the work counter follows the time
        out.push_back({s, estimate.fraction(), end - s, estimate.remainingSeconds()});
    }
    return out;
}

}  // namespace

TEST_CASE("WorkEstimate: monotone share below 100 %, an ETA that grows while a heavy tail drains", "[io][progress]") {
    // Cut-out blockers replay after the opaque ones and cost far more: the last 6000 items take
    // 30 times as long (sponza-like spends a third of its cast in its last 1 % of triangles).
    const uint64_t items = 100000;
    const auto points = runSchedule(items, 4096, [&](uint64_t i) { return uint64_t(i >= items - 6000 ? 3000 : 100); });
    REQUIRE(points.size() > 40);
    double last = 0;
    for (const EstimatePoint& p : points) {
        CHECK(p.fraction >= last);
        CHECK(p.fraction < 1.0);
        last = p.fraction;
    }
    // Between 12 s and 22 s the same chunk is cast: counting items alone would keep an ETA under
    // 1.5 s for the 15 s still to go; the work in flight makes it grow instead.
    const auto at = [&](double s) { return *std::find_if(points.begin(), points.end(), [&](const EstimatePoint& p) { return p.seconds >= s; }); };
    REQUIRE(at(12.0).eta);
    REQUIRE(at(21.0).eta);
    CHECK(*at(21.0).eta > 3 * *at(12.0).eta);
    CHECK(*at(21.0).eta > 0.5 * at(21.0).remaining);
}

TEST_CASE("WorkEstimate: work in flight past its expectation raises the ETA", "[io][progress]") {
    penumbra::WorkEstimate e(100);
    e.sample(0.5, 25, 500);  // the first work: no rate yet
    CHECK(!e.remainingSeconds());
    e.sample(1.0, 50, 1000);  // 20 units an item so far: 1000 more expected, at 1000 a second
    REQUIRE(e.remainingSeconds());
    CHECK(*e.remainingSeconds() == Approx(1.0));
    CHECK(e.fraction() == Approx(0.5));
    e.sample(2.0, 50, 2000);  // the next items took all of it and are still running
    CHECK(*e.remainingSeconds() == Approx(500.0 / 1000));  // taken as two-thirds done
    CHECK(e.fraction() == Approx(0.8));
    e.sample(3.0, 100, 2500);  // every item finished: the closing line says 100 %, not this
    CHECK(e.fraction() == Approx(0.999));
    CHECK(!e.remainingSeconds());
}

TEST_CASE("WorkEstimate without work is the items' share with a linear ETA", "[io][progress]") {
    penumbra::WorkEstimate e(1000);
    e.sample(0.5, 0, 0);
    CHECK(e.fraction() == 0);
    CHECK(!e.remainingSeconds());
    e.sample(1.0, 250, 0);
    CHECK(e.fraction() == Approx(0.25));
    CHECK(*e.remainingSeconds() == Approx(3.0));
    CHECK(formatProgressLine("cast", 250, 1000, 1.0, e.fraction(), e.remainingSeconds()) ==
          "[cast] 25.0% (250/1000) elapsed 1.0s ETA 3.0s");
}

TEST_CASE("WorkEstimate: the rate counts from the first work, not from the phase's start", "[io][progress]") {
    // The receiver hierarchy takes 2 s to build, then 1000 units a second for 200 items of 10 each.
    penumbra::WorkEstimate e(200);
    e.sample(1.0, 0, 0);
    e.sample(2.5, 50, 500);
    e.sample(3.0, 100, 1000);
    REQUIRE(e.remainingSeconds());
    CHECK(*e.remainingSeconds() == Approx(1.0));  // not 3.0 s, from the phase's start
    // Items that finish with no work since the first sample give no rate, not an infinite ETA.
    penumbra::WorkEstimate flat(200);
    flat.sample(1.0, 10, 100);
    flat.sample(2.0, 20, 100);
    CHECK(!flat.remainingSeconds());
}

TEST_CASE("WorkEstimate with runs: a costly last run is expected at its own cost once begun", "[io][progress]") {
    // 1000 items at 10 units, then 100 cut-outs at 1000: the second run is nine tenths of the work.
    penumbra::WorkEstimate plain(1100), runs(1100);
    runs.setRuns({1000, 100});
    for (penumbra::WorkEstimate* e : {&plain, &runs}) {
        e->sample(0.5, 100, 1000);
        e->sample(1.0, 1000, 10000);
        e->sample(2.0, 1010, 20000);  // ten cut-outs done: 90 to go, 90,000 units at 10,000 a second
    }
    REQUIRE(runs.remainingSeconds());
    CHECK(*runs.remainingSeconds() == Approx(90000.0 / (19000.0 / 1.5)));
    CHECK(*plain.remainingSeconds() < 0.2 * *runs.remainingSeconds());  // one mean: 20,000 / 1010 an item
    // Runs that do not divide the total are ignored: one run, as without them.
    penumbra::WorkEstimate odd(1100);
    odd.setRuns({1000, 99});
    odd.sample(0.5, 100, 1000), odd.sample(1.0, 1000, 10000), odd.sample(2.0, 1010, 20000);
    CHECK(*odd.remainingSeconds() == Approx(*plain.remainingSeconds()));
    // A replay played twice (two memory tiles) repeats its runs.
    penumbra::WorkEstimate twice(2200);
    twice.setRuns({1000, 100});
    twice.sample(0.5, 100, 1000), twice.sample(1.0, 1000, 10000), twice.sample(2.0, 1100, 110000);
    REQUIRE(twice.remainingSeconds());
    CHECK(*twice.remainingSeconds() == Approx((1000 * 10.0 + 100 * 1000.0) / (109000.0 / 1.5)));
}

TEST_CASE("WorkEstimate: items restored from a checkpoint count as done, not in the cost per item", "[io][progress]") {
    // Two of three memory tiles restored (200 items, no work), then 100 items of 100 units each.
    penumbra::WorkEstimate e(300);
    e.sample(0.5, 200, 0, 200);
    CHECK(e.fraction() == Approx(200.0 / 300));
    CHECK(!e.remainingSeconds());  // nothing cast yet: no cost per item
    e.sample(1.0, 210, 1000, 200);
    CHECK(e.fraction() == Approx(200.0 / 300 + 100.0 / 300 * 1000 / (1000 + 9000)));
    e.sample(2.0, 220, 2000, 200);
    REQUIRE(e.remainingSeconds());
    CHECK(*e.remainingSeconds() == Approx(8.0));  // 80 items at 100 units, 1000 a second; not 0.7 s
}
