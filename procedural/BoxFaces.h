#pragma once
/// @file BoxFaces.h
/// @brief The 12 triangles of an axis-aligned box, shared by the generators that emit boxes.

namespace penumbra {

/// Corner c of a box has x from bit 0, y from bit 1, z from bit 2. Two triangles per face, wound
/// counter-clockwise seen from outside: -x, +x, -y, +y, -z, +z.
inline constexpr int kBoxFaceTriangles[12][3] = {{0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}, {0, 1, 5}, {0, 5, 4},
                                                 {2, 6, 7}, {2, 7, 3}, {0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}};

}  // namespace penumbra
