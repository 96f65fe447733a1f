#include "bake/cast/ReachCull.h"

#include <glm/common.hpp>

#include <memory>

namespace penumbra {

ReachCull::ReachCull(const std::vector<ConvexBound>& lightBounds, const ReceiverSet& receivers) {
    if (receivers.position.empty()) return;  // nothing to shadow: every blocker goes
    Box around{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
    for (const glm::vec3& p : receivers.position) around.lo = glm::min(around.lo, p), around.hi = glm::max(around.hi, p);
    for (const ConvexBound& bound : lightBounds) reach_.emplace_back(around, bound);
}

bool ReachCull::mayBlock(const Triangle& t) const {
    const Box box{glm::min(glm::min(t.v[0], t.v[1]), t.v[2]), glm::max(glm::max(t.v[0], t.v[1]), t.v[2])};
    bool ballMade = false;
    Ball ball;
    for (const LightReach& reach : reach_) {
        if (!reach.boxMeets(box)) continue;
        if (!ballMade) {
            const glm::dvec3 v[3] = {glm::dvec3(t.v[0]), glm::dvec3(t.v[1]), glm::dvec3(t.v[2])};
            ball = boundingBall(v), ballMade = true;
        }
        if (!reach.hull.misses(ball)) return true;
    }
    return false;
}

BlockerFilter makeReachCull(const std::vector<ConvexBound>& lightBounds, const ReceiverSet& receivers) {
    auto cull = std::make_shared<const ReachCull>(lightBounds, receivers);
    return [cull](const Triangle& t) { return cull->mayBlock(t); };
}

}  // namespace penumbra
