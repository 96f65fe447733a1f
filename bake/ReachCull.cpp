#include "bake/ReachCull.h"

#include <glm/common.hpp>

#include <memory>

namespace penumbra {

ReachCull::ReachCull(const std::vector<ConvexBound>& lightBounds, const ReceiverSet& receivers) {
    if (receivers.position.empty()) return;  // nothing to shadow: every blocker goes
    Box around{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
    for (const glm::vec3& p : receivers.position) around.lo = glm::min(around.lo, p), around.hi = glm::max(around.hi, p);
    const glm::dvec3 lo(around.lo), hi(around.hi);
    const glm::dvec3 corners[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {lo.x, hi.y, lo.z}, {hi.x, hi.y, lo.z},
                                   {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {lo.x, hi.y, hi.z}, {hi.x, hi.y, hi.z}};
    const Ball receiverBall = boundingBall(corners);
    for (const ConvexBound& bound : lightBounds) {
        Box reach = around;
        for (const glm::dvec3& v : bound.vertices)
            reach.lo = glm::min(reach.lo, roundToFloat(v, true)), reach.hi = glm::max(reach.hi, roundToFloat(v, false));
        boxes_.push_back(reach);
        hulls_.emplace_back(boundingBall(bound.vertices), receiverBall);
    }
}

bool ReachCull::mayBlock(const Triangle& t) const {
    const glm::vec3 lo = glm::min(glm::min(t.v[0], t.v[1]), t.v[2]), hi = glm::max(glm::max(t.v[0], t.v[1]), t.v[2]);
    bool ballMade = false;
    Ball ball;
    for (size_t l = 0; l < boxes_.size(); ++l) {
        const Box& r = boxes_[l];
        if (!(lo.x <= r.hi.x && hi.x >= r.lo.x && lo.y <= r.hi.y && hi.y >= r.lo.y && lo.z <= r.hi.z && hi.z >= r.lo.z))
            continue;
        if (!ballMade) {
            const glm::dvec3 v[3] = {glm::dvec3(t.v[0]), glm::dvec3(t.v[1]), glm::dvec3(t.v[2])};
            ball = boundingBall(v), ballMade = true;
        }
        if (!hulls_[l].misses(ball)) return true;
    }
    return false;
}

BlockerFilter makeReachCull(const std::vector<ConvexBound>& lightBounds, const ReceiverSet& receivers) {
    auto cull = std::make_shared<const ReachCull>(lightBounds, receivers);
    return [cull](const Triangle& t) { return cull->mayBlock(t); };
}

}  // namespace penumbra
