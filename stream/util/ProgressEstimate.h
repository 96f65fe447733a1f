#pragma once
/// @file ProgressEstimate.h
/// @brief The share of a phase done and the time it still needs, from measured work as well as
/// from the count of finished items.
///
/// A cast reports two counters: items with a known total (triangles cast, each tile crediting one
/// per tile count as it casts, and the rest of its share when it finishes a chunk) and work with
/// an unknown total (hierarchy nodes visited and exact tests, whose count follows the time spent
/// whatever else runs on the machine). Work per item varies a lot along the stream, and the mean
/// so far predicted the rest better than a recent window did (docs/performance.md, "Progress and
/// ETA"). Between two changes of the item count, the work already spent on the next items counts
/// against what they are expected to need; when it exceeds that, they are heavier than the mean
/// and are taken as two-thirds done, so the ETA grows rather than sitting near zero.
///
/// Runs. When the items come in runs that cost differently (a bucket replay's opaque triangles,
/// then its cut-outs, which cost up to 60 times as much each), each run's items are expected to
/// cost what that run's finished items cost, and a run not begun what every finished item cost on
/// average. Without runs the whole phase is one run.
///
/// Rate. The remaining time is the work expected over the rate of work since the first sample
/// that had any: the time before it (building the receiver hierarchy) does no work.

#include <cstdint>
#include <optional>
#include <vector>

namespace penumbra {

/// @brief Turns samples of (seconds, items, work) into a fraction done and a remaining time.
/// Not thread-safe: one thread (the progress display) samples and reads it.
class WorkEstimate {
public:
    /// @param totalItems the items the phase will finish (> 0)
    explicit WorkEstimate(uint64_t totalItems);

    /// @brief Sets the runs: item counts in the order the items finish, summing to a period that
    /// divides the total (a replay played once per memory tile repeats its runs). Ignored, leaving
    /// one run, when they do not. Call before the first sample.
    void setRuns(std::vector<uint64_t> runs);

    /// @brief Records the counters at @p seconds since the phase began. Counters never decrease.
    /// @param skipped how many of @p items were done without work (tiles restored from a
    ///        checkpoint): they count as done, but not in what an item is expected to cost, nor
    ///        in the rate. They are taken to come before the items finished since the last sample.
    void sample(double seconds, uint64_t items, uint64_t work, uint64_t skipped = 0);

    /// @brief The share done, in [0, 0.999]: never lower than a previous answer, and 0.999 once
    /// the items reach their total (the phase's closing line says 100 %, not a running one).
    /// Without work (0 so far) it is items / total.
    double fraction() const { return fraction_; }
    /// @brief Seconds still needed; nullopt before anything is done or once every item is.
    std::optional<double> remainingSeconds() const { return remaining_; }

private:
    /// How many of the @p count items from item @p first fall in each run.
    std::vector<uint64_t> countByRun(uint64_t first, uint64_t count) const;
    /// The work the items after @p items are expected to need, @p cast of them done with work.
    double expectedWork(uint64_t items, uint64_t cast) const;

    uint64_t total_;
    std::vector<uint64_t> runs_;  ///< one run of total_ items unless setRuns() was given others
    uint64_t period_;             ///< the sum of runs_
    std::vector<double> runItems_, runWork_;  ///< finished items per run, and the work they took
    uint64_t itemsSeen_ = 0, workAtItems_ = 0;  ///< the items last seen, and the work when they changed
    uint64_t skippedSeen_ = 0;                   ///< the skipped items last seen
    struct WorkAt {
        double seconds;
        uint64_t work;
    };
    std::optional<WorkAt> firstWork_;  ///< the first sample with work: the rate is measured from it
    double fraction_ = 0;
    std::optional<double> remaining_;
};

}  // namespace penumbra
