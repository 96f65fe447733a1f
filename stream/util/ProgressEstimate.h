#pragma once
/// @file ProgressEstimate.h
/// @brief The share of a phase done and the time it still needs, from measured work as well as
/// from the count of finished items.
///
/// A cast reports two counters: items with a known total (triangles cast, each tile crediting its
/// share of a chunk when it finishes it)
/// and work with an unknown total (hierarchy nodes visited and exact tests, whose count follows
/// the time spent whatever else runs on the machine). Work per item varies a lot along the
/// stream, and the mean so far predicted the rest better than a recent window did
/// (docs/performance.md, "Progress and ETA"). Items finish a tile's chunk at a time, so between
/// two the work already spent on the next ones counts against what they are expected to need; when it exceeds that, they are heavier than the mean and are taken as
/// two-thirds done, so the ETA grows rather than sitting near zero while the last chunk drains.

#include <cstdint>
#include <optional>

namespace penumbra {

/// @brief Turns samples of (seconds, items, work) into a fraction done and a remaining time.
/// Not thread-safe: one thread (the progress display) samples and reads it.
class WorkEstimate {
public:
    /// @param totalItems the items the phase will finish (> 0)
    explicit WorkEstimate(uint64_t totalItems);

    /// @brief Records the counters at @p seconds since the phase began. Counters never decrease.
    void sample(double seconds, uint64_t items, uint64_t work);

    /// @brief The share done, in [0, 0.999]: never lower than a previous answer, and 0.999 once
    /// the items reach their total (the phase's closing line says 100 %, not a running one).
    /// Without work (0 so far) it is items / total.
    double fraction() const { return fraction_; }
    /// @brief Seconds still needed; nullopt before anything is done or once every item is.
    std::optional<double> remainingSeconds() const { return remaining_; }

private:
    uint64_t total_;
    uint64_t itemsSeen_ = 0, workAtItems_ = 0;  ///< the items last seen, and the work when they changed
    double fraction_ = 0;
    std::optional<double> remaining_;
};

}  // namespace penumbra
