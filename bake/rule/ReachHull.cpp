#include "bake/rule/ReachHull.h"

#include "stream/Triangle.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace penumbra {

Ball boundingBall(std::span<const glm::dvec3> points) {
    glm::dvec3 lo(INFINITY), hi(-INFINITY);
    for (const glm::dvec3& p : points) lo = glm::min(lo, p), hi = glm::max(hi, p);
    Ball b{(lo + hi) * 0.5, 0.0};
    double scale = 1.0, squared = 0.0;  // one square root per ball: this runs for every blocker
    for (const glm::dvec3& p : points) {
        const glm::dvec3 d = p - b.center;
        squared = std::max(squared, glm::dot(d, d));
        scale = std::max({scale, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
    }
    b.radius = std::sqrt(squared) + 1e-9 * scale;
    return b;
}

ReachHull::ReachHull(const Ball& light, const Ball& receivers) : a_(light), b_(receivers) {
    const glm::dvec3 d = b_.center - a_.center;
    length_ = glm::length(d);
    const double scale = std::max({1.0, std::abs(a_.center.x), std::abs(a_.center.y), std::abs(a_.center.z),
                                   std::abs(b_.center.x), std::abs(b_.center.y), std::abs(b_.center.z),
                                   a_.radius, b_.radius, length_});
    margin_ = 1e-9 * scale;
    single_ = !(length_ > std::abs(a_.radius - b_.radius));
    if (single_) {
        if (b_.radius > a_.radius) a_ = b_;
        return;
    }
    axis_ = d / length_;
    sin_ = (a_.radius - b_.radius) / length_;
    cos_ = std::sqrt(std::max(0.0, 1.0 - sin_ * sin_));
}

DirectionCone boundingCone(std::span<const glm::dvec3> directions) {
    DirectionCone c;
    glm::dvec3 sum(0.0);
    for (const glm::dvec3& d : directions) sum += glm::normalize(d);
    if (!(glm::length(sum) > 0.0)) return c.all = true, c;
    c.axis = glm::normalize(sum);
    double cosHalf = 1.0;
    for (const glm::dvec3& d : directions) cosHalf = std::min(cosHalf, glm::dot(glm::normalize(d), c.axis));
    const double half = std::acos(std::clamp(cosHalf, -1.0, 1.0)) + 1e-9;
    if (!(half < 0.5 * std::numbers::pi)) return c.all = true, c;
    c.cosHalf = std::cos(half), c.sinHalf = std::sin(half);
    return c;
}

ReachHull::ReachHull(const DirectionCone& light, const Ball& receivers) : b_(receivers) {
    single_ = false, cone_ = true, everywhere_ = light.all;
    axis_ = light.axis, cos_ = light.cosHalf, sin_ = light.sinHalf;
    margin_ = 1e-9 * std::max({1.0, std::abs(b_.center.x), std::abs(b_.center.y), std::abs(b_.center.z), b_.radius});
}

double ReachHull::distance(const glm::dvec3& p) const {
    if (everywhere_) return -INFINITY;
    if (cone_) {
        // Distance from q = p - centre to the cone (apex 0), in the plane of the axis and q; then
        // the ball's radius. Inside when q is within the half angle of the axis; nearest to the
        // apex when q is more than 90 degrees beyond the cone's boundary ray.
        const glm::dvec3 q = p - b_.center;
        const double t = glm::dot(q, axis_);
        const double rho = std::sqrt(std::max(0.0, glm::dot(q, q) - t * t));
        const double beside = rho * cos_ - t * sin_;
        if (beside <= 0.0) return -b_.radius;
        if (t * cos_ + rho * sin_ <= 0.0) return std::sqrt(glm::dot(q, q)) - b_.radius;
        return beside - b_.radius;
    }
    const glm::dvec3 v = p - a_.center;
    if (single_) return glm::length(v) - a_.radius;
    // In the plane of the axis and p: q = (x, r). The hull's boundary there is an arc of a's
    // circle, the outer tangent segment, and an arc of b's circle.
    const double x = glm::dot(v, axis_);
    const double r = std::sqrt(std::max(0.0, glm::dot(v, v) - x * x));
    // Position along the tangent line, from a's tangent point (a.radius * n) towards b's.
    // Plain square roots, not std::hypot (several times slower): scene coordinates are far from
    // overflow, and the rounding is within margin_.
    const double u = (x - a_.radius * sin_) * cos_ - (r - a_.radius * cos_) * sin_;
    if (u < 0.0) return std::sqrt(glm::dot(v, v)) - a_.radius;
    if (u > length_ * cos_) return std::sqrt((x - length_) * (x - length_) + r * r) - b_.radius;
    return x * sin_ + r * cos_ - a_.radius;
}

namespace {

/// The box around the receivers and the light's bound. A sun's rays leave the receivers towards
/// infinity: along every axis on which some direction of the bound has a positive (negative)
/// component, the box is unbounded above (below).
Box reachBox(const Box& receivers, const ConvexBound& bound) {
    Box reach = receivers;
    for (const glm::dvec3& v : bound.vertices) {
        if (!bound.directional()) {
            reach.lo = glm::min(reach.lo, roundToFloat(v, true)), reach.hi = glm::max(reach.hi, roundToFloat(v, false));
            continue;
        }
        for (int a = 0; a < 3; ++a) {
            if (v[a] > 0.0) reach.hi[a] = INFINITY;
            if (v[a] < 0.0) reach.lo[a] = -INFINITY;
        }
    }
    return reach;
}

ReachHull reachHull(const Box& receivers, const ConvexBound& bound) {
    const glm::dvec3 lo(receivers.lo), hi(receivers.hi);
    const glm::dvec3 corners[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {lo.x, hi.y, lo.z}, {hi.x, hi.y, lo.z},
                                   {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {lo.x, hi.y, hi.z}, {hi.x, hi.y, hi.z}};
    if (bound.directional()) return ReachHull(boundingCone(bound.vertices), boundingBall(corners));
    return ReachHull(boundingBall(bound.vertices), boundingBall(corners));
}

}  // namespace

LightReach::LightReach(const Box& receivers, const ConvexBound& bound)
    : box(reachBox(receivers, bound)), hull(reachHull(receivers, bound)) {}

}  // namespace penumbra
