#pragma once
/// @file AreaSort.h
/// @brief Coarse blocker sorting in memory: largest triangles first (Laine & Aila 2005, Section
/// 3.3). Finding big shadows early lets umbra bits and rebuilds shrink the problem sooner.

#include "stream/Triangle.h"

#include <span>

namespace penumbra {

/// @brief Sorts by decreasing area; equal areas keep stream order, so the result is deterministic.
void sortByAreaDescending(std::span<Triangle> triangles);

}  // namespace penumbra
