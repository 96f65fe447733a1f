#include "bucket/AreaSort.h"

#include <algorithm>
#include <numeric>
#include <vector>

namespace penumbra {

void sortByAreaDescending(std::span<Triangle> triangles) {
    std::vector<std::pair<float, uint32_t>> keys(triangles.size());
    for (size_t i = 0; i < triangles.size(); ++i) keys[i] = {triangles[i].area(), uint32_t(i)};
    std::stable_sort(keys.begin(), keys.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    std::vector<Triangle> sorted(triangles.size());
    for (size_t i = 0; i < keys.size(); ++i) sorted[i] = triangles[keys[i].second];
    std::copy(sorted.begin(), sorted.end(), triangles.begin());
}

}  // namespace penumbra
