#pragma once
/// @file Placement.h
/// @brief Where scattered generators (grass, flowers, forest, scatter) put their items: how many,
/// over which rectangle, and on which ground (a horizontal plane or an inline terrain). Shared
/// so that every generator reads "count", "density", "area", "terrain" and "base_height" the
/// same way.

#include "procedural/TerrainGenerator.h"
#include "stream/util/Random.h"

#include <cstdint>
#include <memory>

namespace penumbra {

class JsonParams;

struct Placement {
    Area area{-1, -1, 1, 1};                      ///< items are placed uniformly over this rectangle
    uint64_t count = 0;                           ///< number of items
    std::shared_ptr<const TerrainField> terrain;  ///< ground surface; null for the plane y = baseHeight
    double baseHeight = 0;                        ///< height of the plane when there is no terrain

    /// Ground height under (x, z): the terrain's triangulated surface, or the plane.
    double groundHeight(double x, double z) const { return terrain ? terrain->height(x, z) : baseHeight; }
    /// Bytes held for the ground: an inline terrain's coordinates and heights (up to 48 MiB).
    uint64_t residentBytes() const { return terrain ? terrain->bytes() : 0; }
    /// Fills the terrain's height cache: the owning source's read() calls it (TerrainField).
    void prepare() const {
        if (terrain) terrain->prepare();
    }
};

/// @brief Reads "count" or "density" (items per square world unit over the area, rounded to the
/// nearest integer), "area", "terrain" (an inline terrain object, TerrainGenerator.h) and
/// "base_height". With a terrain, the area defaults to the terrain's and must lie inside it.
/// @param defaultCount count when neither "count" nor "density" is given
/// @param maxCount largest count allowed (so that count x triangles per item fits 64 bits)
/// @throw InputError naming the key: negative or too large count, both count and density,
///        an empty area, an area outside the terrain, base_height together with terrain.
Placement parsePlacement(const JsonParams& j, uint64_t defaultCount, uint64_t maxCount);

/// A uniform random point of @p area, drawn from @p rng (two draws).
inline void randomPoint(const Area& area, Rng& rng, double& x, double& z) {
    x = area.x0 + area.sizeX() * rng.uniform();
    z = area.z0 + area.sizeZ() * rng.uniform();
}

}  // namespace penumbra
