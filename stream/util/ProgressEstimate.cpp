#include "stream/util/ProgressEstimate.h"

#include <algorithm>

namespace penumbra {

namespace {
/// The highest share a running phase shows: only its closing line says "100 %".
constexpr double kBeforeDone = 0.999;
}  // namespace

WorkEstimate::WorkEstimate(uint64_t totalItems)
    : total_(std::max<uint64_t>(totalItems, 1)), runs_{total_}, period_(total_), runItems_(1, 0.0), runWork_(1, 0.0) {}

void WorkEstimate::setRuns(std::vector<uint64_t> runs) {
    std::erase(runs, 0);
    uint64_t period = 0;
    for (uint64_t r : runs) period += r;
    if (runs.empty() || period == 0 || total_ % period != 0) return;
    runs_ = std::move(runs), period_ = period;
    runItems_.assign(runs_.size(), 0.0), runWork_.assign(runs_.size(), 0.0);
}

std::vector<uint64_t> WorkEstimate::countByRun(uint64_t first, uint64_t count) const {
    const uint64_t periods = count / period_;
    std::vector<uint64_t> perRun(runs_.size());
    for (size_t k = 0; k < runs_.size(); ++k) perRun[k] = periods * runs_[k];
    uint64_t position = first % period_, left = count - periods * period_;
    size_t k = 0;
    uint64_t runEnd = runs_[0];
    while (left > 0) {
        while (position >= runEnd) runEnd += runs_[++k];
        const uint64_t take = std::min(left, runEnd - position);
        perRun[k] += take;
        left -= take, position += take;
        if (position == period_) position = 0, k = 0, runEnd = runs_[0];
    }
    return perRun;
}

double WorkEstimate::expectedWork(uint64_t items, uint64_t cast) const {
    const std::vector<uint64_t> left = countByRun(items, total_ - items);
    const double mean = double(workAtItems_) / double(cast);
    double expected = 0;
    for (size_t k = 0; k < runs_.size(); ++k) expected += double(left[k]) * (runItems_[k] > 0 ? runWork_[k] / runItems_[k] : mean);
    return expected;
}

void WorkEstimate::sample(double seconds, uint64_t items, uint64_t work, uint64_t skipped) {
    skipped = std::min(skipped, items);
    if (items > itemsSeen_) {
        // The work since the items last changed went to the items finished since, less the
        // skipped ones (before them): shared out over their runs by count.
        const uint64_t newlySkipped = std::min(skipped - std::min(skipped, skippedSeen_), items - itemsSeen_);
        const uint64_t count = items - itemsSeen_ - newlySkipped, first = itemsSeen_ + newlySkipped;
        const std::vector<uint64_t> perRun = count > 0 ? countByRun(first, count) : std::vector<uint64_t>{};
        const double workPerItem = count > 0 ? double(work - workAtItems_) / double(count) : 0.0;
        for (size_t k = 0; k < perRun.size(); ++k) runItems_[k] += double(perRun[k]), runWork_[k] += workPerItem * double(perRun[k]);
    }
    skippedSeen_ = std::max(skippedSeen_, skipped);
    if (items != itemsSeen_) itemsSeen_ = items, workAtItems_ = work;
    const uint64_t cast = items - skipped;  // items done with work
    if (items >= total_) {  // only the closing line says 100 %
        fraction_ = kBeforeDone;
        remaining_.reset();
        return;
    }
    // Time is measured from the first work: what ran before it (building the receiver hierarchy)
    // is not part of the rate, and on GRIDS it made the first ETA 200 times too long.
    const bool firstWork = work > 0 && !firstWork_;
    if (firstWork) firstWork_ = WorkAt{seconds, work};
    double share;
    if (work == 0 || cast == 0 || workAtItems_ == 0) {  // nothing measured yet: the items' share, a linear ETA
        share = double(items) / double(total_);
        if (cast > 0) remaining_ = seconds * double(total_ - items) / double(cast);
        else remaining_.reset();
    } else {
        const double expected = expectedWork(items, cast);
        const double inFlight = double(work - workAtItems_);
        // Continuous in inFlight: both terms meet at two-thirds of the expected work.
        const double left = std::max(expected - inFlight, 0.5 * inFlight);
        // The skipped items are done; the rest of the share follows the work.
        const double skippedShare = double(skipped) / double(total_);
        share = skippedShare + (1.0 - skippedShare) * double(work) / (double(work) + left);
        if (firstWork || seconds <= firstWork_->seconds || work <= firstWork_->work) remaining_.reset();  // no rate yet
        else remaining_ = (seconds - firstWork_->seconds) * left / double(work - firstWork_->work);
    }
    fraction_ = std::max(fraction_, std::min(share, kBeforeDone));
}

}  // namespace penumbra
