#pragma once
/// @file PolygonTriangulation.h
/// @brief The one rule that turns an OBJ face of n corners into n - 2 triangles, shared by the
/// blocker stream (ObjReader) and the receiver meshes (IndexedMesh), so that both see the same
/// surface.

#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

/// @brief Triangulates a polygon of @p corners (n >= 3, in order around it) into exactly n - 2
/// triangles of corner indices, each wound as the polygon is.
///
/// A convex polygon (every corner turns the same way about its Newell normal, collinear corners
/// allowed) gives the fan (0, k, k + 1), as OBJ readers traditionally do. A concave one is
/// ear-clipped in the plane of its Newell normal: the fan of an L-shaped face covers ground
/// outside the face, and a blocker there casts shadow where there is no geometry. A polygon with
/// no ear left (self-intersecting, or degenerate) clips its first remaining convex corner, so the
/// count is always n - 2. A face whose clipping would take more than about a second (hundreds of
/// thousands of corners, concave) gives what is left of it as a fan. The same corners always give
/// the same triangles.
/// @param out replaced with the triangles.
void triangulatePolygon(std::span<const glm::vec3> corners, std::vector<std::array<uint32_t, 3>>& out);

}  // namespace penumbra
