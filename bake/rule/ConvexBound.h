#pragma once
/// @file ConvexBound.h
/// @brief Convex bounding shapes of light samples: the polygon Delta_L / Delta_Gk of the paper, or a
/// convex bounding volume for volumetric lights.

#include <glm/vec3.hpp>

#include <array>
#include <span>
#include <vector>

namespace penumbra {

/// @brief A convex polytope given by its vertices and edges. For planar lights the vertices are a
/// convex polygon in the light plane (a prism of tiny thickness when float rounding lifts samples
/// off the plane); for volumetric lights a box. Only vertices and edges are needed to enumerate
/// the separating planes of a penumbra volume.
struct ConvexBound {
    std::vector<glm::dvec3> vertices;
    std::vector<std::array<int, 2>> edges;
    /// 1: the vertices are points. 0: they are directions towards a light at infinity (a sun),
    /// lying on the plane at unit distance along the sun's axis; the bound is then a cone of
    /// directions, and every plane test takes them as homogeneous points (x, 0).
    double w = 1.0;
    bool directional() const { return w == 0.0; }
};

/// @brief Bounds points that lie (up to float rounding) in the plane through @p origin spanned by
/// the orthonormal axes @p u, @p v with normal @p n. Picks the smallest-area of: the (u,v) box,
/// the 8-direction polygon (octagon) and, when it has at most 8 vertices, the convex hull.
/// @param extraCandidate optional polygon (in 3D, in the plane) tried as well, used only if it
/// contains every point, e.g. the light's own outline.
ConvexBound boundPlanarPoints(std::span<const glm::dvec3> points, const glm::dvec3& origin,
                              const glm::dvec3& u, const glm::dvec3& v, const glm::dvec3& n,
                              std::span<const glm::dvec3> extraCandidate = {});

/// @brief Axis-aligned bounding box of 3D points as a 8-vertex, 12-edge polytope.
ConvexBound boundPoints3D(std::span<const glm::dvec3> points);

}  // namespace penumbra
