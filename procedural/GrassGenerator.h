#pragma once
/// @file GrassGenerator.h
/// @brief "grass": blades as tapered, bent triangle strips, scattered over a rectangle or a
/// terrain (stratified: consecutive blades share one of about count / 64 equal tiles, so coverage
/// is even and the stream spatially coherent). Blade b is a pure function of (parameters, seed,
/// b) and every blade has the same number of triangles, so triangle i belongs to blade
/// i / segments and nothing is stored: a billion blades cost no memory.

#include "procedural/Noise.h"
#include "procedural/Placement.h"
#include "stream/SourceRegistry.h"

#include <glm/vec2.hpp>

namespace penumbra {

/// @brief The optional clump mask: an fBm field that thins blades out into clumps and bare
/// patches while keeping the blade count exact.
///
/// Each blade draws up to `tries` candidate positions (the first in its own placement tile, the
/// others anywhere in the area) and takes the first one where the mask is at least `threshold`;
/// if none qualifies it takes the candidate with the highest mask value.
/// So the count stays exactly what was asked for, bare patches keep only a rare straggler
/// (about bareFraction^tries of the blades), and blades near a clump's edge (mask within `edge`
/// above the threshold) are shortened, down to 40% of their height, so clumps look rounded.
struct ClumpParams {
    bool enabled = false;
    FbmParams noise{3, 0.5, 2.0, 0.5};
    double threshold = 0.0;  ///< mask values below this are bare; the mask lies in [-1, 1]
    double edge = 0.3;       ///< width of the shortening band above the threshold, in mask units
    int tries = 8;           ///< candidate positions per blade, 1..64
    uint64_t seed = 0;       ///< mask seed; defaults to one derived from the grass seed
};

struct GrassParams {
    Placement placement;                    ///< count (or density), area, ground
    int segments = 5;                       ///< triangles per blade, 3..7
    glm::dvec2 height{0.2, 0.5};            ///< blade height range (world units)
    glm::dvec2 width{0.01, 0.03};           ///< blade width at the root (world units)
    glm::dvec2 bend{0.1, 0.4};              ///< tip's horizontal offset as a fraction of the height
    glm::dvec2 orientationDeg{0.0, 360.0};  ///< facing (= bend) direction about +y, degrees from +x
    ClumpParams clump;
    bool alphaMatte = false;  ///< flag every blade triangle kTriangleAlphaMatte
    uint64_t seed = 1;
};

/// @brief Parses a "grass" geometry entry.
/// @throw InputError naming the bad key ("scene.json: geometry[0].count: must be in 0..N, got -5").
GrassParams parseGrassParams(const SourceRequest& request);

/// @brief The grass stream: sizeHint() = count x segments.
TriangleSourcePtr makeGrassSource(const GrassParams& params);

/// @brief Root centre of blade @p blade (the midpoint of its first two vertices), for tests and
/// tools: (x, ground height at x, z).
glm::dvec3 grassBladeRoot(const GrassParams& params, uint64_t blade);

}  // namespace penumbra
