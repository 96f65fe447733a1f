#include "stream/util/ProgressEstimate.h"

#include <algorithm>

namespace penumbra {

namespace {
/// The highest share a running phase shows: only its closing line says "100 %".
constexpr double kBeforeDone = 0.999;
}  // namespace

WorkEstimate::WorkEstimate(uint64_t totalItems) : total_(std::max<uint64_t>(totalItems, 1)) {}

void WorkEstimate::sample(double seconds, uint64_t items, uint64_t work) {
    if (items != itemsSeen_) itemsSeen_ = items, workAtItems_ = work;
    if (items >= total_) {  // what is left (a last pass over the results) is not counted
        fraction_ = kBeforeDone;
        remaining_.reset();
        return;
    }
    double share;
    if (work == 0 || items == 0 || workAtItems_ == 0) {  // nothing measured yet: the items' share, a linear ETA
        share = double(items) / double(total_);
        if (items > 0) remaining_ = seconds * double(total_ - items) / double(items);
        else remaining_.reset();
    } else {
        const double expected = double(workAtItems_) / double(items) * double(total_ - items);
        const double inFlight = double(work - workAtItems_);
        // Continuous in inFlight: both terms meet at two-thirds of the expected work.
        const double left = std::max(expected - inFlight, 0.5 * inFlight);
        share = double(work) / (double(work) + left);
        remaining_ = seconds * left / double(work);
    }
    fraction_ = std::max(fraction_, std::min(share, kBeforeDone));
}

}  // namespace penumbra
