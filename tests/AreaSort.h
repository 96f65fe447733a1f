#pragma once
/// @file AreaSort.h
/// @brief The tests' exact in-memory version of the coarse blocker sort (Laine & Aila 2005,
/// Section 3.3): largest triangles first, equal areas in stream order. The bake uses the area
/// buckets of bucket/ instead; the in-memory reference path of TestScenes.h uses this.

#include "stream/Triangle.h"

#include <algorithm>
#include <span>
#include <utility>
#include <vector>

namespace penumbra::test {

inline void sortByAreaDescending(std::span<Triangle> triangles) {
    std::vector<std::pair<float, uint32_t>> keys(triangles.size());
    for (size_t i = 0; i < triangles.size(); ++i) keys[i] = {triangles[i].area(), uint32_t(i)};
    std::stable_sort(keys.begin(), keys.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    std::vector<Triangle> sorted(triangles.size());
    for (size_t i = 0; i < keys.size(); ++i) sorted[i] = triangles[keys[i].second];
    std::copy(sorted.begin(), sorted.end(), triangles.begin());
}

}  // namespace penumbra::test
