#pragma once
/// @file SolidSelfIntersection.h
/// @brief Whether a closed solid's triangles cross one another, for ClosedSolidScan.
///
/// Closed casters skip the faces of a closed solid that turn away from the whole light. That is
/// exact when the winding number of the surface is never negative: along a segment from a light
/// sample (outside every solid) to a receiver, a crossing of a skipped face lowers the winding
/// number, so a face that blocks must have raised it before. Edge balance (EdgeBalance.h) and a
/// positive volume do not ensure it: a watertight box whose top face is pushed down through its
/// bottom face has a wedge of winding number -1, and receivers in it lost the bottom face's
/// shadow (a stop-58 sweep: 192 of 192 relations). Without crossings, every closed component
/// wound outward has winding number 0 or 1, and their sum is never negative.
///
/// The test is conservative: a pair of triangles is "crossing" unless a separating plane proves
/// that they meet at most at the vertices they share (matched by exact float values, as the rule
/// sees them). A separating axis is sought among the planes' normals, the edges' cross products
/// and the in-plane edge normals; one triangle must lie beyond it by more than a rounding bound,
/// the other on the other side up to a rounding bound. Triangles that only touch (within that
/// bound) without sharing the vertex count as crossing: such a solid is cast as an open surface,
/// which is exact, only slower.

#include "bake/cast/EdgeBalance.h"
#include "stream/Triangle.h"

#include <glm/vec3.hpp>

#include <cstddef>
#include <span>
#include <vector>

namespace penumbra {

/// @brief A triangle's corners, as the solid check holds them (36 bytes).
struct SolidTriangle {
    glm::vec3 v[3];
};

/// @brief Whether triangles @p a and @p b may meet anywhere other than at the corners they share.
/// @return false only when a separating plane proves they do not.
bool trianglesMayCross(const SolidTriangle& a, const SolidTriangle& b);

/// @brief Whether any two of @p triangles may cross (trianglesMayCross()); pairs are found by a
/// sweep over their boxes along the solid's longest axis. Degenerate triangles (no area) are left
/// out: they bound nothing. Reorders @p triangles.
bool solidMayCrossItself(std::vector<SolidTriangle>& triangles);

/// @brief What the parts of a solid show (triangles joined through shared edges, corners matched
/// by exact float values).
struct SolidParts {
    /// A part is wound inward or flat: its signed volume is not positive beyond rounding. It has
    /// winding number -1 inside, whatever its place in the stream (the scan's running check sees
    /// only parts whose triangles are contiguous).
    bool inward = false;
    /// An edge is used by more than two triangles. Two sheets that cross along a line of shared
    /// edges (a fold welded where it passes through itself, an extruded figure eight) meet only
    /// at edges that both share, where no pair of triangles crosses: trianglesMayCross() cannot
    /// see them (a stop-58 sweep: 1,536 of 1,536 relations lost). Such a solid is treated as
    /// crossing; so are two solids of one entry that share an edge, which only costs speed.
    bool sharedEdge = false;
};
SolidParts solidParts(const std::vector<SolidTriangle>& triangles);

/// Triangles of one solid that the scan holds to check it; a larger solid is cast as open.
inline constexpr size_t kMaxCheckedSolidTriangles = size_t(1) << 16;
/// Bytes the scan holds for those checks at most: the triangles (sorted in place), and while the
/// parts are found three edge indices, a parent and a part's volume sums per triangle.
inline constexpr size_t kSolidCheckBytes = kMaxCheckedSolidTriangles * (sizeof(SolidTriangle) + 4 * sizeof(uint32_t) + sizeof(OutwardVolume));

}  // namespace penumbra
