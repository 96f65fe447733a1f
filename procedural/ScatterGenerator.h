#pragma once
/// @file ScatterGenerator.h
/// @brief "scatter": N instances of any geometry source (an OBJ or glTF file, or another
/// generator, given inline as "source") with random position, rotation about +y and scale, on a
/// plane or a terrain.
///
/// Instances are streamed, never copied: when the source has at most `cache_triangles`
/// triangles (default 1M, 40 MB) it is read once and kept, and instances are transformed from
/// that copy in parallel; a larger source is re-streamed from its start once per instance. Either
/// way instance k is placed by a hash of (seed, k), so the output is a pure function of the
/// parameters and the source.

#include "procedural/Placement.h"
#include "stream/SourceRegistry.h"

#include <glm/vec2.hpp>

namespace penumbra {

/// Deepest nesting of scatter sources (a scatter of a scatter of ...): each level is opened by a
/// recursive call, and no real scene needs more than a few.
inline constexpr int kMaxScatterNesting = 16;

struct ScatterParams {
    Placement placement;                 ///< count (or density), area, ground
    glm::dvec2 scale{1.0, 1.0};          ///< uniform scale range
    glm::dvec2 rotationDeg{0.0, 360.0};  ///< rotation about +y, degrees
    uint64_t cacheTriangles = 1000000;   ///< largest source kept in memory
    uint64_t seed = 1;
};

/// @brief Opens a "scatter" entry, including its inline "source" (which may carry its own
/// "transform", applied before the instance placement).
/// @throw InputError naming the bad key, or whatever opening or reading the source throws.
TriangleSourcePtr openScatterSource(const SourceRequest& request);

/// @brief Scatters instances of @p source (the source is owned and read from its start).
/// @param where location for messages about the count ("scene.json: geometry[2]")
TriangleSourcePtr makeScatterSource(const ScatterParams& params, TriangleSourcePtr source, const std::string& where);

}  // namespace penumbra
