#pragma once
/// @file ReachCull.h
/// @brief "Never write to disk what cannot block": the reach culls of the caster, applied in the
/// bucket pass, so that blockers out of every light's reach never reach a bucket file.
///
/// A blocker can only block a segment from a receiver to a light sample if it meets the convex
/// hull of the light's bound and the receivers. The same LightReach tests the caster makes first
/// (BlockerBatch.h) are made here against *all* receivers, which the scan pass has found by
/// the time the bucket pass starts: the box around the light's bound and the receivers, then the
/// hull of a ball around the light and one around the receivers (ReachHull.h). A tile's
/// receivers lie inside all receivers, so a blocker culled here is one no tile could use, and the
/// masks do not change. The caster still makes its own, tighter per-tile tests.
///
/// The cull is a predicate (BlockerFilter), so the bucket pass does not depend on how reach is
/// decided; makeReachCull() is the one the pipeline uses.

#include "bake/light/Light.h"
#include "bake/rule/Plane.h"
#include "bake/rule/ReachHull.h"
#include "receivers/ReceiverSet.h"
#include "stream/Triangle.h"

#include <functional>
#include <vector>

namespace penumbra {

/// @brief True when a blocker may block something and must be kept.
using BlockerFilter = std::function<bool(const Triangle&)>;

/// @brief The reach of every light over a set of receivers.
class ReachCull {
public:
    /// @param lightBounds Delta_L per light (LightSamples::lightBounds); a sun's are directions.
    /// @param receivers every receiver the bake will cast (not just one tile's).
    ReachCull(const std::vector<ConvexBound>& lightBounds, const ReceiverSet& receivers);

    /// @brief False only when @p t misses every light's reach box, or the reach hull of every
    /// light whose box it meets.
    bool mayBlock(const Triangle& t) const;

private:
    std::vector<LightReach> reach_;  // per light, around every receiver
};

/// @brief The bucket pass's filter for @p receivers and @p lightBounds, as a BlockerFilter.
BlockerFilter makeReachCull(const std::vector<ConvexBound>& lightBounds, const ReceiverSet& receivers);

}  // namespace penumbra
