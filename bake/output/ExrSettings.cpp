#include "bake/output/ExrSettings.h"

#include "stream/util/Error.h"

namespace penumbra {

bool parseExrPixelType(const std::string& value, const std::string& where) {
    if (value == "float") return false;
    if (value == "half") return true;
    fail(where, "expected \"float\" or \"half\", got \"{}\"", value);
}

int checkExrTileSize(int64_t size, const std::string& where) {
    // Below 16 the per-tile overhead dominates; above 1024 a row of tiles is a large buffer.
    if (size != 0 && (size < 16 || size > 1024)) fail(where, "expected 0 (scanlines) or a tile size in 16..1024, got {}", size);
    return int(size);
}

ExrSettings parseExrSettings(const JsonParams& j) {
    ExrSettings s;
    if (j.has("pixel_type")) s.format.half = parseExrPixelType(j.string("pixel_type"), j.where("pixel_type"));
    if (j.has("tile_size")) s.format.tileSize = checkExrTileSize(j.integer("tile_size", INT32_MIN, INT32_MAX), j.where("tile_size"));
    const std::string rgb = j.string("rgb", "irradiance");
    if (rgb == "irradiance") s.colour = ExrColour::Irradiance;
    else if (rgb == "visibility") s.colour = ExrColour::Visibility;
    else fail(j.where("rgb"), "expected \"irradiance\" or \"visibility\", got \"{}\"", rgb);
    j.finish();
    return s;
}

}  // namespace penumbra
