#pragma once
/// @file CreaseNormals.h
/// @brief Smooth shading normals for meshes that come without them (an OBJ without `vn`, a glTF
/// without NORMAL), with hard edges kept where faces meet at more than a crease angle.
///
/// Each triangle corner gets the angle-weighted mean (Thürmer & Wüthrich 1998) of the unit
/// normals of the faces around its position whose normal is within the crease angle of the
/// corner's own face, so a finely tessellated sphere shades smoothly while a cube keeps six flat
/// faces. Faces around a position are found by welding (MeshTopology.h), so vertices split by
/// the loader at UV seams still smooth together. A vertex whose corners get different normals is
/// split into one vertex per normal; the other attributes are copied.

#include "stream/IndexedMesh.h"

namespace penumbra {

inline constexpr double kDefaultCreaseAngleDeg = 60.0;

/// @brief @p mesh with shading normals by crease angle (its own normals are ignored).
/// @param creaseDeg faces whose normals differ by more than this do not smooth each other; in
///        [0, 180] (180 smooths everything, 0 only coplanar faces)
/// Corners of degenerate (zero-area) triangles take the mean of every face around them, or a
/// zero normal when there is none (the lightmap rasterizer then uses no receiver cosine).
IndexedMesh withCreaseNormals(const IndexedMesh& mesh, double creaseDeg);

}  // namespace penumbra
