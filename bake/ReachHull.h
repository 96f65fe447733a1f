#pragma once
/// @file ReachHull.h
/// @brief The convex hull of two balls, one around a light and one around every receiver: every
/// segment from a light sample to a receiver lies inside it, so a blocker whose bounding ball
/// misses it blocks nothing. A few dozen flops per blocker, against hundreds for a penumbra
/// volume: this is the root cull for blockers inside the reach box but beside the light.

#include <glm/vec3.hpp>

#include <span>

namespace penumbra {

/// A ball (centre and radius).
struct Ball {
    glm::dvec3 center{0.0};
    double radius = 0.0;
};

/// @brief A ball around @p points (centre of their box, radius to the farthest point), enlarged by
/// a relative 1e-9 so that roundoff never leaves a point outside.
Ball boundingBall(std::span<const glm::dvec3> points);

class ReachHull {
public:
    ReachHull() = default;
    ReachHull(const Ball& light, const Ball& receivers);

    /// @brief Distance from @p p to the hull (negative inside), exact up to roundoff.
    double distance(const glm::dvec3& p) const;

    /// @brief True when @p ball certainly does not meet the hull (with a relative margin).
    bool misses(const Ball& ball) const { return distance(ball.center) > ball.radius + margin_; }

private:
    Ball a_, b_;           // a_ at x = 0, b_ at x = length_ along axis_
    glm::dvec3 axis_{0.0};
    double length_ = 0.0;
    double sin_ = 0.0, cos_ = 1.0;  // outer tangent's normal in the (axial, radial) plane
    bool single_ = true;           // one ball contains the other: the hull is that ball
    double margin_ = 0.0;
};

}  // namespace penumbra
