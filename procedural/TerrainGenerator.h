#pragma once
/// @file TerrainGenerator.h
/// @brief "terrain": a heightfield grid over a rectangle, displaced by fBm gradient noise. It is
/// also the ground that grass, flowers, forests and scattered instances stand on; they query
/// terrainHeight(), which interpolates the emitted triangles rather than the noise, so that
/// whatever is planted sits exactly on the surface that casts and receives shadows.

#include "procedural/Noise.h"
#include "stream/SourceRegistry.h"

#include <cstdint>
#include <memory>
#include <vector>

namespace penumbra {

class JsonParams;

/// @brief An axis-aligned rectangle in the xz plane, [x0, x1] x [z0, z1] (world units).
struct Area {
    double x0 = -10, z0 = -10, x1 = 10, z1 = 10;
    double sizeX() const { return x1 - x0; }
    double sizeZ() const { return z1 - z0; }
    double extent() const { return sizeX() * sizeZ(); }
    bool contains(const Area& o) const { return o.x0 >= x0 && o.x1 <= x1 && o.z0 >= z0 && o.z1 <= z1; }
};

/// @brief Reads `key` as [[x0, z0], [x1, z1]].
/// @throw InputError naming the key when it is malformed or empty (x1 <= x0 or z1 <= z0).
Area parseArea(const JsonParams& j, const std::string& key, const Area& fallback);

struct TerrainParams {
    Area area;                ///< the rectangle covered
    int cellsX = 64;          ///< grid cells along x
    int cellsZ = 64;          ///< grid cells along z
    double amplitude = 1.0;   ///< largest deviation from baseHeight (world units)
    double baseHeight = 0.0;  ///< height of the zero level of the noise
    FbmParams noise;          ///< octaves, frequency (cycles per world unit), lacunarity, gain
    uint64_t seed = 1;
};

/// @brief Parses terrain parameters from an object (a geometry entry or an inline "terrain"
/// object) and calls finish() on it.
/// @throw InputError naming the bad key.
TerrainParams parseTerrainParams(const JsonParams& j);
TerrainParams parseTerrainParams(const SourceRequest& request);

/// x of grid column @p i, as the emitted vertices have it (float, so surface queries match).
double terrainVertexX(const TerrainParams& p, int64_t i);
/// z of grid row @p k, likewise.
double terrainVertexZ(const TerrainParams& p, int64_t k);
/// Height of grid vertex (i, k), rounded to float exactly as it is emitted.
float terrainVertexHeight(const TerrainParams& p, int64_t i, int64_t k);

/// @brief Height of the triangulated terrain surface at (x, z): the linear interpolation over the
/// grid triangle containing the point (each cell is split along its (i, k)-(i+1, k+1) diagonal).
/// Points outside the area take the height of the nearest edge cell's plane.
double terrainHeight(const TerrainParams& p, double x, double z);

/// @brief terrainHeight() with the grid's vertex heights cached when there are at most
/// kCachedVertices of them (16 MiB of floats); larger grids evaluate the noise on demand. Both
/// paths give the same bits, so the cache is filled by prepare(), which the owning source calls
/// on its first read: after the memory plan has counted bytes(), never while the scene opens.
/// Thread-safe for reading between prepare() calls.
class TerrainField {
public:
    static constexpr uint64_t kCachedVertices = uint64_t(1) << 22;

    explicit TerrainField(const TerrainParams& params);
    const TerrainParams& params() const { return p_; }
    float vertexHeight(int64_t i, int64_t k) const;
    double vertexX(int64_t i) const { return xs_[size_t(i)]; }
    double vertexZ(int64_t k) const { return zs_[size_t(k)]; }
    double height(double x, double z) const;
    /// @brief Fills the height cache (once; single-threaded callers only, before parallel reads).
    void prepare() const;
    /// Bytes it holds once prepared: the vertex coordinates and the cached heights.
    uint64_t bytes() const { return (xs_.size() + zs_.size()) * sizeof(double) + (cached() ? vertices() * sizeof(float) : 0); }

private:
    TerrainParams p_;
    Fbm noise_;
    std::vector<double> xs_, zs_;  // vertex coordinates, terrainVertexX/Z
    uint64_t vertices() const { return uint64_t(xs_.size()) * uint64_t(zs_.size()); }
    bool cached() const { return vertices() <= kCachedVertices; }
    mutable std::vector<float> heights_;  // (cellsX + 1) * (cellsZ + 1), row-major in k; empty until prepare()
};

TriangleSourcePtr makeTerrainSource(const TerrainParams& params);

}  // namespace penumbra
