#pragma once
/// @file ReachHull.h
/// @brief The convex hull of two balls, one around a light and one around every receiver: every
/// segment from a light sample to a receiver lies inside it, so a blocker whose bounding ball
/// misses it blocks nothing. For a sun the light is a cone of directions, and the hull is the
/// receivers' ball swept to infinity along the cone. A few dozen flops per blocker, against
/// hundreds for a penumbra volume: this is the root cull for blockers inside the reach box but
/// beside the light.

#include "bake/rule/ConvexBound.h"
#include "bake/rule/Plane.h"

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

/// A cone of directions with its apex at the origin: every d with angle(d, axis) <= the half angle.
struct DirectionCone {
    glm::dvec3 axis{0, 0, 1};  ///< unit
    double cosHalf = 1.0, sinHalf = 0.0;
    bool all = false;  ///< the half angle reaches 90 degrees: treated as every direction
};

/// @brief A cone containing every direction of @p directions (not necessarily unit), widened by
/// a relative 1e-9 rad so that roundoff never leaves one outside.
DirectionCone boundingCone(std::span<const glm::dvec3> directions);

class ReachHull {
public:
    ReachHull() = default;
    ReachHull(const Ball& light, const Ball& receivers);
    /// The receivers' ball swept to infinity along @p light: every ray from a receiver towards a
    /// sun sample lies inside it.
    ReachHull(const DirectionCone& light, const Ball& receivers);

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
    bool cone_ = false;            // b_ swept along the cone axis_ / cos_ / sin_ (a sun)
    bool everywhere_ = false;      // a cone of 90 degrees or more: nothing is culled
    double margin_ = 0.0;
};

/// @brief Where a light's blockers can be. A blocker can only block a segment (or ray) from a
/// receiver to a sample of the light if it meets their convex hull: this is the box around the
/// light's bound and the receivers (for a sun, unbounded along every axis its directions point
/// along) and, finer, the ReachHull of a ball around each (the receivers' ball swept along a
/// sun's cone). Both the caster's root cull and the bucket pass's cull before spill use it.
struct LightReach {
    Box box;
    ReachHull hull;

    LightReach(const Box& receivers, const ConvexBound& bound);
    /// @brief False when a blocker with box @p b and bounding ball @p ball blocks nothing here.
    bool mayReach(const Box& b, const Ball& ball) const { return boxMeets(b) && !hull.misses(ball); }
    bool boxMeets(const Box& b) const {
        return b.lo.x <= box.hi.x && b.hi.x >= box.lo.x && b.lo.y <= box.hi.y && b.hi.y >= box.lo.y &&
               b.lo.z <= box.hi.z && b.hi.z >= box.lo.z;
    }
};

}  // namespace penumbra
