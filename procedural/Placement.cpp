#include "procedural/Placement.h"

#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"
#include "stream/util/Random.h"

#include <cmath>

namespace penumbra {

Placement parsePlacement(const JsonParams& j, uint64_t defaultCount, uint64_t maxCount) {
    Placement p;
    if (const nlohmann::json* t = j.raw("terrain")) {
        JsonParams tj(*t, j.file(), j.path("terrain"));
        p.terrain = std::make_shared<const TerrainField>(parseTerrainParams(tj));
        p.area = p.terrain->params().area;
        if (j.has("base_height")) fail(j.where("base_height"), "cannot be combined with \"terrain\" (the terrain gives the height)");
    }
    p.baseHeight = j.number("base_height", 0.0);
    if (!(std::abs(p.baseHeight) <= 1e9)) fail(j.where("base_height"), "must be within +-1e9, got {}", p.baseHeight);
    p.area = parseArea(j, "area", p.area);
    if (p.terrain && !p.terrain->params().area.contains(p.area))
        fail(j.where("area"), "must lie inside the terrain's area");

    if (j.has("count") && j.has("density")) fail(j.where("density"), "give either \"count\" or \"density\", not both");
    p.count = uint64_t(j.integer("count", int64_t(defaultCount), 0, int64_t(maxCount)));
    if (j.has("density")) {
        const double density = j.number("density");
        if (!(density >= 0)) fail(j.where("density"), "must not be negative, got {}", density);
        const double n = std::round(density * p.area.extent());
        if (!(n <= double(maxCount)))
            fail(j.where("density"), "gives {} items over the area, more than the limit of {}", n, maxCount);
        p.count = uint64_t(n);
    }
    return p;
}

}  // namespace penumbra
