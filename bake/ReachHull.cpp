#include "bake/ReachHull.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

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

double ReachHull::distance(const glm::dvec3& p) const {
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

}  // namespace penumbra
