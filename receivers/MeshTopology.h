#pragma once
/// @file MeshTopology.h
/// @brief Connectivity of an indexed triangle mesh as a surface: vertices welded by position,
/// the triangles around each welded vertex, and the neighbour across each manifold edge.
///
/// Loaders split a vertex wherever an attribute differs (an OBJ corner with another vt, a glTF
/// UV seam), so the index buffer alone does not say which triangles touch. Welding by exact
/// position (float bits; +0 and -0 are the same point) recovers the surface. An edge joins two
/// triangles only when exactly two non-degenerate triangles use it; edges of one triangle
/// (boundaries) or of three or more (non-manifold fins) join nothing, so charts and smoothing
/// never cross them.

#include "stream/IndexedMesh.h"

#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

inline constexpr uint32_t kNoTriangle = ~0u;

/// @brief The welded connectivity of one mesh.
struct MeshTopology {
    std::vector<uint32_t> weld;       ///< per vertex: its welded id (equal positions share one)
    uint32_t welded = 0;              ///< number of welded ids
    std::vector<uint32_t> across;     ///< per edge 3t+k (corner k to k+1): the triangle across it, or kNoTriangle
    std::vector<uint32_t> ringStart;  ///< welded + 1 offsets into ring
    std::vector<uint32_t> ring;       ///< the triangles around each welded vertex, in index order

    /// Triangles touching welded vertex @p w (a degenerate triangle may appear twice).
    std::span<const uint32_t> around(uint32_t w) const {
        return {ring.data() + ringStart[w], ring.data() + ringStart[w + 1]};
    }
};

/// @brief Welds @p mesh's vertices by position and finds its manifold edges.
/// Degenerate triangles (two corners welded together) get no neighbours and are no neighbour.
MeshTopology buildMeshTopology(const IndexedMesh& mesh);

}  // namespace penumbra
