#pragma once
/// @file Progress.h
/// @brief A one-line progress display for long phases.
///
/// Work is counted with a relaxed atomic add, so worker threads can call update() per item
/// without measurable cost; all formatting and I/O happens on a separate thread that wakes
/// every 0.25 s. On a terminal the line is redrawn in place with '\r'; when stderr is a file
/// or pipe (CI logs) a full line is printed at most every 2 s so logs stay short.

#include "stream/util/ProgressEstimate.h"
#include "stream/util/Timer.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>

namespace penumbra {

/// @brief Thrown by ProgressReporter::update() once requestCancel() was called: long work is
/// where progress is reported, so that is where a library caller (the Python module's Ctrl-C)
/// can stop a bake. It unwinds like any error, so no output or temp file is left behind.
class Cancelled : public std::runtime_error {
public:
    Cancelled() : std::runtime_error("cancelled") {}
};

/// Set by requestCancel(); read with one relaxed load per update().
inline std::atomic<bool> cancelFlag{false};
/// @brief Makes every ProgressReporter::update() from now on throw Cancelled (any thread).
inline void requestCancel() { cancelFlag.store(true, std::memory_order_relaxed); }
/// @brief Clears requestCancel(), before the next piece of work.
inline void clearCancel() { cancelFlag.store(false, std::memory_order_relaxed); }

/// @brief What the phase running now has done, for callers that show progress their own way
/// (the Python module's callback) instead of on stderr.
struct ProgressSnapshot {
    std::string phase;
    uint64_t done = 0, total = 0;  ///< total 0: unknown
    double elapsedSeconds = 0;
    double fraction = 0;  ///< the share done as the display shows it (WorkEstimate; 0 when total is 0)
    std::optional<double> remainingSeconds;  ///< the display's ETA
};
/// @brief The most recently started ProgressReporter still running, in any thread, quiet or not;
/// nullopt between phases. Thread safe.
std::optional<ProgressSnapshot> currentProgress();

/// @brief pbrt-style progress line on stderr: `[phase] 42.0% (4200/10000) elapsed 3.1s ETA 4.3s`.
class ProgressReporter {
public:
    /// @param phase short name shown in brackets, e.g. "bucket" or "bake".
    /// @param totalWork units of work expected; 0 means unknown (no percentage or ETA).
    /// @param quiet when true nothing is printed and no thread is started.
    ProgressReporter(std::string phase, uint64_t totalWork, bool quiet);
    /// Calls done(), unless an exception is unwinding through the owner, in which case the
    /// display is just stopped: claiming "done" on the way to an error message would mislead.
    ~ProgressReporter();

    ProgressReporter(const ProgressReporter&) = delete;
    ProgressReporter& operator=(const ProgressReporter&) = delete;

    /// @brief Records @p work more units as finished. Thread safe; one relaxed atomic add.
    /// @throw Cancelled after requestCancel().
    void update(uint64_t work = 1) {
        done_.fetch_add(work, std::memory_order_relaxed);
        if (cancelFlag.load(std::memory_order_relaxed)) throw Cancelled();
    }

    /// @brief Records @p items more units as finished and @p work more units of measured effort
    /// spent on them, whose total is unknown (a cast's visits: ProgressEstimate.h). Once any work
    /// is reported the share and ETA shown follow the work, not the count of items. Thread safe
    /// and never throws, for worker tasks that must not unwind: the caller's own update() calls
    /// are where it is cancelled.
    void updateMeasured(uint64_t items, uint64_t work) noexcept {
        work_.fetch_add(work, std::memory_order_relaxed);
        done_.fetch_add(items, std::memory_order_relaxed);
    }

    /// @brief Runs of items that cost differently (WorkEstimate::setRuns()), before any update.
    void setRuns(std::vector<uint64_t> runs) {
        std::lock_guard lock(estimateMutex_);
        estimate_.setRuns(std::move(runs));
    }

    /// @brief Records @p items more units as done without work (a tile restored from a
    /// checkpoint): they count in the share, not in the ETA's cost per item or its rate.
    /// @throw Cancelled after requestCancel().
    void skip(uint64_t items) {
        skipped_.fetch_add(items, std::memory_order_relaxed);
        update(items);
    }

    /// @brief Stops the display thread and prints the final line with the total time.
    /// Idempotent.
    void done();
    /// @brief Stops the display thread without the final line: the phase did not finish (it was
    /// left before its end). Idempotent, and done() after it prints nothing.
    void abandon() { stop(false); }

    /// @brief Holds the display while a phase nested in this one shows its own line (the shading
    /// of one memory tile's receivers, between that tile's cast and the next). On a terminal the
    /// line drawn so far stays above the nested one. The time paused counts neither in the
    /// elapsed time shown nor in the ETA's rate. Thread safe; pausing twice is pausing once.
    void pause();
    /// @brief Shows the line again after pause(), from the next redraw.
    void resume();

    /// Units of work reported so far.
    uint64_t workDone() const { return done_.load(std::memory_order_relaxed); }
    /// Units of work expected (0: unknown).
    uint64_t totalWork() const { return total_; }
    /// The phase's name.
    const std::string& phase() const { return phase_; }
    /// Seconds since construction, less the time paused (pause()).
    double elapsedSeconds() const;
    /// @brief Samples the counters now and returns the share done and the ETA (WorkEstimate), as
    /// the display shows them. Thread safe.
    ProgressSnapshot snapshot() const;

private:
    void run();
    void stop(bool printFinal);
    void print(const std::string& line, bool final);

    std::string phase_;
    uint64_t total_;
    bool quiet_;
    bool tty_ = false;
    int uncaughtAtStart_;
    std::atomic<uint64_t> done_{0};
    std::atomic<uint64_t> work_{0};  ///< updateMeasured()'s work
    std::atomic<uint64_t> skipped_{0};  ///< skip()'s items, also in done_
    std::atomic<bool> paused_{false};
    double pausedSeconds_ = 0, pausedAt_ = 0;  ///< guarded by estimateMutex_: time held by pause()
    mutable std::mutex estimateMutex_;
    mutable WorkEstimate estimate_;  ///< guarded by estimateMutex_; sampled by snapshot()
    Stopwatch clock_;

    std::mutex mutex_;
    std::condition_variable wake_;
    bool stopping_ = false;  // guarded by mutex_
    bool finished_ = false;  // guarded by mutex_
    std::mutex printMutex_;  // held while a line is written, so that pause() ends the line last
    size_t lastWidth_ = 0;   // guarded by printMutex_
    std::thread thread_;
};

/// @brief The text of one progress line (without '\r' or '\n'); exposed for tests.
/// @param final true for the closing line, which shows total time instead of an ETA.
std::string formatProgressLine(std::string_view phase, uint64_t done, uint64_t total,
                               double elapsedSeconds, bool final);

/// @brief A line before the end, with the share done and the remaining time estimated elsewhere
/// (WorkEstimate): `[cast] 42.0% (4200/10000) elapsed 3.1s ETA 4.3s`.
std::string formatProgressLine(std::string_view phase, uint64_t done, uint64_t total, double elapsedSeconds,
                               double fraction, std::optional<double> remainingSeconds);

/// @brief While one is alive on a thread, readers that check a whole file when they are opened
/// there (an OBJ of 32 MiB or more: every statement before the first triangle) show that pass as
/// a phase of its own, `[check mesh.obj] 42.0% (bytes/bytes) ...`, and so does the load of an
/// OBJ's indexed meshes (`[load mesh.obj]`: receivers, `convert` to glTF), quiet or not as given (quiet
/// still feeds currentProgress(), the Python module's callback). A bake opens its sources inside
/// one, so that a 20 GB OBJ is not minutes of silence before its scan; elsewhere (tests, tools)
/// readers stay silent.
class OpeningProgress {
public:
    /// Files from this size on show their opening passes (about 120 MB/s: from a quarter second up).
    static constexpr uint64_t kShownFromBytes = 32ull << 20;
    explicit OpeningProgress(bool quiet);
    ~OpeningProgress();
    OpeningProgress(const OpeningProgress&) = delete;
    OpeningProgress& operator=(const OpeningProgress&) = delete;
    /// @brief The innermost scope's quiet flag on this thread; nullopt outside any scope.
    static std::optional<bool> active();

private:
    std::optional<bool> outer_;
};

/// @brief A reader's pass over a file's bytes on opening, shown as a phase (`[check mesh.obj]`,
/// `[load mesh.obj]`) inside an OpeningProgress scope when the file has at least
/// OpeningProgress::kShownFromBytes; otherwise nothing. Positions are reported in 1 MiB steps.
class OpeningPhase {
public:
    OpeningPhase(const std::string& phase, uint64_t fileBytes) : total_(fileBytes) {
        if (const std::optional<bool> quiet = OpeningProgress::active(); quiet && fileBytes >= OpeningProgress::kShownFromBytes)
            reporter_.emplace(phase, fileBytes, *quiet);
    }
    /// @brief The pass has read up to byte @p position.
    void advance(uint64_t position) {
        position = std::min(position, total_);  // a last line without its newline counts one past the end
        if (reporter_ && position > reported_ && position - reported_ >= (1u << 20))
            reporter_->update(position - reported_), reported_ = position;
    }
    /// @brief The whole file was read: the count reaches the total (the "done" line follows
    /// when this goes out of scope, unless an error is unwinding).
    void finish() {
        if (reporter_ && total_ > reported_) reporter_->update(total_ - reported_), reported_ = total_;
    }

private:
    uint64_t total_, reported_ = 0;
    std::optional<ProgressReporter> reporter_;
};

/// @brief Short duration for humans: "3.1s", "2m05s", "1h02m".
std::string formatDuration(double seconds);

}  // namespace penumbra
