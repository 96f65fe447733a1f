#pragma once
/// @file FlowerGenerator.h
/// @brief "flowers": the paper's FLOWERS scene. Each flower is a thin tapered stem with a fan of
/// petals on top and a few arching leaf blades, scattered over a rectangle or a terrain. Every
/// flower has the same triangle count and is a pure function of (parameters, seed, index), so
/// the field streams without being stored.

#include "procedural/Placement.h"
#include "stream/SourceRegistry.h"

#include <glm/vec2.hpp>

namespace penumbra {

struct FlowerParams {
    Placement placement;                  ///< count (or density), area, ground
    glm::dvec2 height{0.25, 0.5};         ///< stem height (world units)
    double stemRadius = 0.006;            ///< stem radius at the root (world units); 60% at the top
    int stemSides = 3;                    ///< sides of the stem prism, 3..8
    int stemSegments = 2;                 ///< stacked stem sections, 1..4
    glm::dvec2 stemBend{0.0, 0.2};        ///< head's horizontal offset as a fraction of the height
    int petals = 6;                       ///< petals in the fan, 3..16 (2 triangles each)
    glm::dvec2 petalLength{0.03, 0.06};   ///< world units
    double petalWidth = 0.6;              ///< petal width as a fraction of its length
    glm::dvec2 petalTiltDeg{10.0, 40.0};  ///< petals rise this far above horizontal, degrees
    int leaves = 2;                       ///< leaf blades on the stem, 0..6 (3 triangles each)
    glm::dvec2 leafLength{0.08, 0.15};    ///< world units
    double leafWidth = 0.015;             ///< leaf width at its base (world units)
    bool alphaMatte = false;              ///< flag every triangle kTriangleAlphaMatte
    /// Petals are cut-outs with the built-in petal outline (stream/AlphaTable.h, kAlphaPetalLower)
    /// and flagged kTriangleAlphaMatte, so each diamond becomes a rounded petal.
    bool petalCutout = true;
    uint64_t seed = 1;
};

/// Triangles per flower: 2 x stemSides x stemSegments + 2 x petals + 3 x leaves.
uint32_t flowerTriangleCount(const FlowerParams& p);

/// @brief Parses a "flowers" entry. @throw InputError naming the bad key.
FlowerParams parseFlowerParams(const SourceRequest& request);
TriangleSourcePtr makeFlowerSource(const FlowerParams& params);

}  // namespace penumbra
