#include "bake/output/ExrSettings.h"

#include "stream/util/Error.h"

#include <utility>

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

ExrCompression parseExrCompression(const std::string& value, const std::string& where) {
    static constexpr std::pair<const char*, ExrCompression> kNames[] = {
        {"none", ExrCompression::None}, {"rle", ExrCompression::Rle},     {"zips", ExrCompression::Zips}, {"zip", ExrCompression::Zip},
        {"piz", ExrCompression::Piz},   {"pxr24", ExrCompression::Pxr24}, {"b44", ExrCompression::B44},   {"b44a", ExrCompression::B44a},
        {"dwaa", ExrCompression::Dwaa}, {"dwab", ExrCompression::Dwab}};
    for (const auto& [name, compression] : kNames)
        if (value == name) return compression;
    fail(where, "expected one of none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa, dwab, got \"{}\"", value);
}

ExrSettings parseExrSettings(const JsonParams& j) {
    ExrSettings s;
    if (j.has("pixel_type")) s.format.half = parseExrPixelType(j.string("pixel_type"), j.where("pixel_type"));
    if (j.has("tile_size")) s.format.tileSize = checkExrTileSize(j.integer("tile_size", INT32_MIN, INT32_MAX), j.where("tile_size"));
    if (j.has("compression")) s.format.compression = parseExrCompression(j.string("compression"), j.where("compression"));
    if (j.has("zip_level")) {
        if (s.format.compression != ExrCompression::Zip && s.format.compression != ExrCompression::Zips)
            fail(j.where("zip_level"), "applies to zip and zips compression only (compression is \"{}\")", j.string("compression"));
        s.format.zipLevel = int(j.integer("zip_level", 1, 9));
    }
    const std::string rgb = j.string("rgb", "irradiance");
    if (rgb == "irradiance") s.colour = ExrColour::Irradiance;
    else if (rgb == "visibility") s.colour = ExrColour::Visibility;
    else fail(j.where("rgb"), "expected \"irradiance\" or \"visibility\", got \"{}\"", rgb);
    j.finish();
    return s;
}

}  // namespace penumbra
