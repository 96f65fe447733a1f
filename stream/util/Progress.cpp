#include "stream/util/Progress.h"

#include <system_error>

#include <fmt/format.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <vector>

namespace penumbra {

namespace {

constexpr auto kRedrawInterval = std::chrono::milliseconds(250);
/// Minimum spacing of lines when stderr is not a terminal.
constexpr double kLogInterval = 2.0;

/// Reporters running now, newest last (currentProgress()).
std::mutex runningMutex;
std::vector<const ProgressReporter*>& running() {
    static std::vector<const ProgressReporter*> reporters;
    return reporters;
}

}  // namespace

std::optional<ProgressSnapshot> currentProgress() {
    std::lock_guard lock(runningMutex);
    if (running().empty()) return std::nullopt;
    return running().back()->snapshot();
}

double ProgressReporter::elapsedSeconds() const {
    std::lock_guard lock(estimateMutex_);
    const double now = clock_.seconds();
    return now - pausedSeconds_ - (paused_.load() ? now - pausedAt_ : 0.0);
}

void ProgressReporter::pause() {
    {
        std::lock_guard lock(estimateMutex_);
        if (paused_.exchange(true)) return;
        pausedAt_ = clock_.seconds();
    }
    // After this no redraw starts (run() looks at paused_ under printMutex_).
    std::lock_guard print(printMutex_);
    if (tty_ && lastWidth_ > 0) std::fputc('\n', stderr), std::fflush(stderr), lastWidth_ = 0;
}

void ProgressReporter::resume() {
    std::lock_guard lock(estimateMutex_);
    if (!paused_.exchange(false)) return;
    pausedSeconds_ += clock_.seconds() - pausedAt_;
}

ProgressSnapshot ProgressReporter::snapshot() const {
    ProgressSnapshot s;
    s.phase = phase_, s.total = total_, s.elapsedSeconds = elapsedSeconds();
    std::lock_guard lock(estimateMutex_);
    s.done = workDone();
    if (total_ == 0) return s;
    s.total = std::max(total_, s.done);
    estimate_.sample(s.elapsedSeconds, s.done, work_.load(std::memory_order_relaxed), skipped_.load(std::memory_order_relaxed));
    s.fraction = estimate_.fraction();
    s.remainingSeconds = estimate_.remainingSeconds();
    return s;
}

std::string formatDuration(double seconds) {
    if (!(seconds >= 0)) seconds = 0;  // also catches NaN
    if (seconds < 60) return fmt::format("{:.1f}s", seconds);
    auto whole = static_cast<uint64_t>(seconds);
    if (whole < 3600) return fmt::format("{}m{:02}s", whole / 60, whole % 60);
    return fmt::format("{}h{:02}m", whole / 3600, whole / 60 % 60);
}

std::string formatProgressLine(std::string_view phase, uint64_t done, uint64_t total,
                               double elapsedSeconds, bool final) {
    std::string line;
    if (total > 0) {
        double fraction = std::min(1.0, static_cast<double>(done) / static_cast<double>(total));
        line = fmt::format("[{}] {:.1f}% ({}/{})", phase, 100.0 * fraction, done, total);
    } else if (done > 0) {
        line = fmt::format("[{}] {}", phase, done);
    } else {
        line = fmt::format("[{}]", phase);  // a phase that counts nothing (writing outputs)
    }
    if (final) return line + fmt::format(" done in {}", formatDuration(elapsedSeconds));
    line += fmt::format(" elapsed {}", formatDuration(elapsedSeconds));
    // Linear extrapolation; only meaningful once some work is done.
    if (total > 0 && done > 0 && done < total) {
        double eta = elapsedSeconds * static_cast<double>(total - done) / static_cast<double>(done);
        line += fmt::format(" ETA {}", formatDuration(eta));
    }
    return line;
}

std::string formatProgressLine(std::string_view phase, uint64_t done, uint64_t total, double elapsedSeconds,
                               double fraction, std::optional<double> remainingSeconds) {
    std::string line = fmt::format("[{}] {:.1f}% ({}/{}) elapsed {}", phase, 100.0 * fraction, done, total,
                                   formatDuration(elapsedSeconds));
    if (remainingSeconds) line += fmt::format(" ETA {}", formatDuration(*remainingSeconds));
    return line;
}

ProgressReporter::ProgressReporter(std::string phase, uint64_t totalWork, bool quiet)
    : phase_(std::move(phase)), total_(totalWork), quiet_(quiet),
      uncaughtAtStart_(std::uncaught_exceptions()), estimate_(totalWork) {
    {
        std::lock_guard lock(runningMutex);
        running().push_back(this);
    }
    if (quiet_) return;
    tty_ = ::isatty(STDERR_FILENO) == 1;
    try {
        thread_ = std::thread([this] { run(); });
    } catch (const std::system_error&) {
        // No thread to be had (a process or address-space limit): only the closing line is printed.
    }
}

ProgressReporter::~ProgressReporter() {
    // An exception passing through the scope that owns us means the phase failed.
    stop(std::uncaught_exceptions() <= uncaughtAtStart_);
}

void ProgressReporter::done() { stop(true); }

void ProgressReporter::stop(bool printFinal) {
    {
        std::lock_guard lock(mutex_);
        if (finished_) return;
        finished_ = true;
        stopping_ = true;
    }
    {
        std::lock_guard lock(runningMutex);
        std::erase(running(), this);
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
    resume();  // a phase that ends paused ends at its own time
    if (quiet_) return;
    std::lock_guard lock(printMutex_);
    if (printFinal)
        // An estimate the work outgrew (an atlas's packings) ends as "(1488/1488)", not 1488/1440.
        print(formatProgressLine(phase_, workDone(), total_ ? std::max(total_, workDone()) : 0, elapsedSeconds(), true), true);
    else if (tty_ && lastWidth_ > 0)
        std::fputc('\n', stderr);  // leave the partial line visible above the error message
}

void ProgressReporter::run() {
    double lastLog = 0;
    std::unique_lock lock(mutex_);
    for (;;) {
        if (wake_.wait_for(lock, kRedrawInterval, [this] { return stopping_; })) return;
        // Sampled at every tick, printed or not, so the estimate sees each finished chunk.
        const ProgressSnapshot s = snapshot();
        if (!tty_) {
            if (s.elapsedSeconds - lastLog < kLogInterval) continue;
            lastLog = s.elapsedSeconds;
        }
        // Format and write without holding the lock so done() never waits on stderr.
        lock.unlock();
        {
            std::lock_guard print(printMutex_);
            if (!paused_.load())
                this->print(total_ > 0 ? formatProgressLine(phase_, s.done, total_, s.elapsedSeconds, s.fraction, s.remainingSeconds)
                                       : formatProgressLine(phase_, s.done, total_, s.elapsedSeconds, false),
                            false);
        }
        lock.lock();
    }
}

void ProgressReporter::print(const std::string& line, bool final) {
    std::string out;
    if (tty_) {
        // Overwrite the previous, possibly longer, line in place.
        out = "\r" + line;
        if (line.size() < lastWidth_) out.append(lastWidth_ - line.size(), ' ');
        lastWidth_ = line.size();
        if (final) out.push_back('\n');
    } else {
        out = line + "\n";
    }
    // One fwrite per line so lines from other threads' messages do not interleave mid-line.
    std::fwrite(out.data(), 1, out.size(), stderr);
    std::fflush(stderr);
}

namespace {
thread_local std::optional<bool> openingQuiet;
}  // namespace

OpeningProgress::OpeningProgress(bool quiet) : outer_(openingQuiet) { openingQuiet = quiet; }
OpeningProgress::~OpeningProgress() { openingQuiet = outer_; }
std::optional<bool> OpeningProgress::active() { return openingQuiet; }

}  // namespace penumbra
