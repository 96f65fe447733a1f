#pragma once
/// @file GridGenerator.h
/// @brief The paper's GRIDS scene: stacked perforated square grids over a floor, casting large
/// overlapping penumbrae.

#include "stream/SourceRegistry.h"

#include <glm/vec3.hpp>

namespace penumbra {

struct GridParams {
    glm::dvec3 center{0.0};  ///< centre of the floor
    double size = 4.0;       ///< side of each grid (world units)
    int cells = 16;          ///< holes per side
    double bar = 0.35;       ///< fraction of a cell taken by the solid bar, (0, 1)
    double thickness = 0.04; ///< bar thickness; 0 makes flat bars (2 triangles per bar segment)
    int levels = 3;          ///< stacked grids
    double height = 1.0;     ///< height of the lowest grid above the floor
    double spacing = 0.6;    ///< vertical distance between grids
    double rotateStep = 15;  ///< each level is turned this many degrees about the vertical axis
    double floorSize = 12.0; ///< side of the floor quad; 0 for no floor
};

/// @brief Parses parameters; throws InputError naming the bad key.
GridParams parseGridParams(const SourceRequest& request);
TriangleSourcePtr makeGridSource(const GridParams& params);

}  // namespace penumbra
