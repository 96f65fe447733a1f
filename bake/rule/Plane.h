#pragma once
/// @file Plane.h
/// @brief Oriented planes and the box/point classifications that penumbra-volume culling uses.

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include <algorithm>
#include <cmath>

namespace penumbra {

/// @brief The plane dot(n, p) + d = 0; the positive side is "inside" every volume built from planes.
struct Plane {
    // Left uninitialised on purpose: volumes hold arrays of planes that are filled as built, and
    // zeroing 32 planes per volume per triangle showed up in profiles.
    glm::dvec3 n;
    double d;

    double eval(const glm::dvec3& p) const { return glm::dot(n, p) + d; }
    static Plane through(const glm::dvec3& normal, const glm::dvec3& point) {
        return {normal, -glm::dot(normal, point)};
    }
    Plane flipped() const { return {-n, -d}; }
};

/// Axis-aligned box with float corners, as stored in the receiver hierarchy.
struct Box {
    glm::vec3 lo{0.0f}, hi{0.0f};
};

/// @brief The largest |coordinate| of any point in @p box: the extent the receiver epsilon
/// (ReceiverEpsilon::at) takes for every receiver inside it.
inline double largestCoordinate(const Box& box) {
    const glm::vec3 far = glm::max(glm::abs(box.lo), glm::abs(box.hi));
    return std::max({far.x, far.y, far.z});
}

/// @brief The largest |coordinate| of @p p.
inline double largestCoordinate(const glm::dvec3& p) { return std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}); }

/// Result of classifying a box against one plane.
enum class BoxSide { Outside, Straddles, Inside };

/// @brief Classifies @p box against @p plane using the box corner nearest to / farthest along n.
inline BoxSide classify(const Plane& plane, const Box& box) {
    glm::dvec3 farthest, nearest;
    for (int i = 0; i < 3; ++i) {
        bool positive = plane.n[i] >= 0.0;
        farthest[i] = positive ? box.hi[i] : box.lo[i];
        nearest[i] = positive ? box.lo[i] : box.hi[i];
    }
    if (plane.eval(farthest) < 0.0) return BoxSide::Outside;
    if (plane.eval(nearest) >= 0.0) return BoxSide::Inside;
    return BoxSide::Straddles;
}

}  // namespace penumbra
