#pragma once
/// @file LightmapReceivers.h
/// @brief Receivers at the texel centres of a mesh's lightmap (Heckbert & Herf 1997's radiance
/// textures, one per polygon, here one atlas per mesh laid out by the mesh's own UVs), and the
/// dilation that keeps bilinear filtering from bleeding the background into the surface.
///
/// Texel (x, y) covers UV [x/W, (x+1)/W] x [y/H, (y+1)/H] (glTF convention: row 0 is v = 0, the
/// top of the image). Rasterization is conservative: a texel any triangle overlaps with positive
/// area gets a receiver, so that bilinear lookups near UV seams always find baked values. The
/// receiver sits at the point of the owning triangle nearest to the texel centre (the centre
/// itself when the triangle contains it), with position and normal interpolated there.

#include "receivers/ReceiverSet.h"
#include "stream/IndexedMesh.h"

#include <glm/vec2.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

/// @brief The UVs a lightmap uses: TEXCOORD_1 (glTF's usual lightmap set) when the mesh has it,
/// else TEXCOORD_0 / OBJ vt; nullptr when it has neither.
const std::vector<glm::vec2>* lightmapUvs(const IndexedMesh& mesh);

/// @brief Whether @p mesh's lightmapUvs() can lay out a lightmap: present, inside [0, 1]^2 (to
/// within kUvTolerance: lightmaps do not wrap, so tiling texture coordinates are no layout), and
/// with a positive total UV area.
bool usableLightmapUvs(const IndexedMesh& mesh);

inline constexpr float kUvTolerance = 1e-3f;

/// @brief A planar receiver polygon with its texture layout: the triangle a lightmap's texels lie
/// on, and each corner's position in texel units (texel (x, y) covers [x, x+1] x [y, y+1]).
struct ReceiverPolygon {
    glm::dvec3 position[3];
    glm::dvec2 texel[3];
};

/// @brief The receiver polygons of a kind whose receivers are texels (Heckbert & Herf's radiance
/// textures, --method hh): per receiver its polygon and texel.
struct ReceiverPolygons {
    std::vector<ReceiverPolygon> polygons;
    std::vector<uint32_t> polygonOf;      ///< per receiver
    std::vector<glm::ivec2> texelOf;      ///< per receiver: its texel (x, y)
};


/// @brief The receivers of one lightmap.
struct LightmapLayout {
    int width = 0, height = 0;
    ReceiverSet receivers;          ///< position and normal per receiver
    std::vector<uint32_t> texel;    ///< per receiver: y * width + x
    std::vector<uint32_t> triangle; ///< per receiver: the mesh triangle it lies on (its texel's owner)
    std::vector<float> coverage;    ///< per texel: UV area covered, in [0, 1] (overlaps saturate)
    uint64_t overlapping = 0;       ///< texels whose centre lies inside more than one triangle
    /// World area of the mesh, and the parts of it that get no texel: UVs outside [0, 1]^2
    /// (lightmaps do not wrap), and triangles with no UV area (noUvTriangles of them).
    double surfaceArea = 0, outsideArea = 0, noUvArea = 0;
    uint64_t noUvTriangles = 0;
};

/// @brief Rasterizes @p mesh's UVs into a @p width x @p height lightmap.
///
/// Each texel belongs to at most one triangle: a triangle containing the texel centre wins over
/// one that merely cuts the texel (so a receiver is clamped only where it must be), and among
/// equals the first in index order wins, which keeps the result deterministic. Triangles with
/// zero UV area cover nothing. Normals are the interpolated shading normals when the mesh has
/// them, else the triangle's geometric normal.
/// @pre lightmapUvs(mesh) is not null; width and height are positive.
LightmapLayout rasterizeLightmap(const IndexedMesh& mesh, int width, int height);

/// @brief Area of the part of triangle @p a, @p b, @p c inside the box [lo, hi] (2-D).
double clippedTriangleArea(glm::dvec2 a, glm::dvec2 b, glm::dvec2 c, glm::dvec2 lo, glm::dvec2 hi);

/// @brief A square lightmap side giving @p texelsPerUnit texels per world unit on average:
/// side = texelsPerUnit * sqrt(world area / UV area), at least 1.
/// @return 0 when the mesh has no UV area (every UV triangle degenerate).
int lightmapSideForDensity(const IndexedMesh& mesh, double texelsPerUnit);

/// @brief Fills unused texels from their neighbours, @p rings rings deep: in each ring every
/// empty texel with at least one filled 8-neighbour becomes the average of those neighbours
/// (as they were at the start of the ring), so values spread outwards one texel per ring.
/// @param channels width*height floats each, modified in place
/// @param filled width*height flags, 1 = holds a value; updated to include the dilated texels
void dilateLightmap(std::span<std::vector<float>* const> channels, std::vector<uint8_t>& filled, int width, int height,
                    int rings);

}  // namespace penumbra
