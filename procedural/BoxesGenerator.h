#pragma once
/// @file BoxesGenerator.h
/// @brief Architecture from axis-aligned boxes (12 triangles each, normals outward):
/// "boxes" takes an explicit list, and "colonnade" builds a SPONZA-like courtyard: an open
/// rectangle ringed by storeys of columns carrying gallery slabs, inside an outer wall.

#include "stream/SourceRegistry.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <vector>

namespace penumbra {

/// An axis-aligned box, lo < hi on every axis (world units).
struct BoxShape {
    glm::dvec3 lo, hi;
};

struct ColonnadeParams {
    glm::dvec3 center{0.0};              ///< centre of the courtyard at ground level
    glm::dvec2 courtyard{16.0, 10.0};    ///< open inner rectangle, x and z extent
    double gallery = 3.0;                ///< depth of the covered gallery between columns and wall
    glm::ivec2 columns{9, 6};            ///< columns along an x side and along a z side (corners shared)
    double columnWidth = 0.5;            ///< square column section
    double storeyHeight = 4.0;           ///< floor to floor
    int storeys = 2;                     ///< stacked galleries
    double slab = 0.35;                  ///< thickness of each gallery ceiling
    double wall = 0.5;                   ///< outer wall thickness; 0 for no wall
    bool floor = true;                   ///< a ground slab (0.1 thick, top at ground level) under everything
};

/// The boxes of a colonnade, in a fixed order (storeys bottom up, then wall, then floor).
std::vector<BoxShape> colonnadeBoxes(const ColonnadeParams& p);

/// @brief Parse "boxes" / "colonnade". @throw InputError naming the bad key.
std::vector<BoxShape> parseBoxes(const SourceRequest& request);
ColonnadeParams parseColonnadeParams(const SourceRequest& request);

/// @brief Streams 12 triangles per box, in order.
TriangleSourcePtr makeBoxSource(std::vector<BoxShape> boxes, const std::string& name = "boxes");

}  // namespace penumbra
