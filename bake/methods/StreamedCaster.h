#pragma once
/// @file StreamedCaster.h
/// @brief The part the methods that stream the blockers in any order share (penumbra-map, hh):
/// they read the blockers in passes of their own, so a receiver kind that wants to see every
/// chunk (CastContext::observeChunk) gets one read of its own, and results reach the sink from the
/// worker threads.

#include "bake/cast/Caster.h"
#include "stream/util/Timer.h"

#include <functional>

namespace penumbra {

class StreamedCaster : public Caster {
public:
    CastStats stats() const override { return castStats_; }

protected:
    explicit StreamedCaster(const CastContext& context) : c_(context) {}

    /// @brief Shows every blocker chunk to the receiver kind, on the first cast only.
    void observeOnce(TriangleSource& blockers);
    /// @brief The receiver kind's chunk observer, on the first call only (empty after, or when the
    /// kind has none), for a method that shows it its own first read instead of observeOnce().
    std::function<void(std::span<const Triangle>)> takeObserver();
    /// @brief Ends the cast's time (begun at @p cast) and calls @p each for receivers
    /// [@p first, @p end) on the worker threads. Shading is not the method's work, and hpc's cast
    /// time leaves it out too: the benches compare the rest.
    void report(const Stopwatch& cast, uint32_t first, uint32_t end, const std::function<void(uint32_t)>& each);

    const CastContext c_;

private:
    CastStats castStats_;  ///< castSeconds: each cast() up to its report, summed
    bool observed_ = false;
};

}  // namespace penumbra
