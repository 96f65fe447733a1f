#include "bake/kinds/LightmapKind.h"

#include "bake/ExrMetadata.h"
#include "bake/output/ImageWriters.h"
#include "bake/output/LightmapGltf.h"
#include "bake/kinds/ReceiverKind.h"
#include "stream/util/PathText.h"
#include "stream/util/Timer.h"
#include "bake/Scene.h"
#include "bake/WorkPlan.h"
#include "receivers/CreaseNormals.h"
#include "receivers/LightmapAtlas.h"
#include "receivers/LightmapReceivers.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/GeometryFile.h"
#include "stream/IndexedMesh.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cctype>
#include <filesystem>
#include <mutex>
#include <optional>
#include <set>

namespace penumbra {
namespace {

constexpr int64_t kMaxSide = 16384;  // 1 GiB of float channels per map is already generous
constexpr const char* kAtlasName = "atlas";  ///< the generated atlas's output suffix

/// Where a mesh's lightmap UVs come from (the "uv" key).
enum class UvSource { Auto, Mesh, Generate };

/// The lightmap keys of the scene's "receivers" object.
struct LightmapSettings {
    UvSource uv = UvSource::Auto;
    int width = 256, height = 256;  ///< "resolution": per mesh, or the atlas's size
    double density = 0;             ///< "texels_per_unit" (instead of resolution)
    int padding = 4;
    double creaseDeg = kDefaultCreaseAngleDeg;
    double chartDeg = kDefaultChartConeDeg;
    bool powerOfTwo = false;
    int maxSide = int(kMaxSide);
    std::string where;              ///< the receivers object, for messages
};

/// One lightmap to bake: a mesh, its size, and after the scan its texel layout.
struct Lightmap {
    IndexedMesh mesh;
    std::string source;  ///< the file, for messages and the EXR header
    std::string label;   ///< for messages: the file, plus the mesh name when the file has several
    std::string name;    ///< output suffix: out/lightmap-NAME.exr
    int width = 0, height = 0;
    size_t first = 0;    ///< index of its first receiver in the kind's ReceiverSet
    LightmapLayout layout;
    /// The entry's receive_shadows and receiver_offset; the atlas's come per mesh (classEnds).
    ReceiverClass receiverClass;
    /// The atlas: mesh m's triangles end at classEnds[m] in the concatenated mesh, and take classes[m].
    std::vector<size_t> classEnds;
    std::vector<ReceiverClass> classes;
};

/// The receiver classes of @p map on its layout's receivers (before they join the kind's set).
void applyClasses(Lightmap& map) {
    ReceiverSet& set = map.layout.receivers;
    for (size_t r = 0; r < set.size(); ++r) {
        if (map.classEnds.empty()) {
            applyReceiverClass(set, r, map.receiverClass);
            continue;
        }
        const size_t m = size_t(std::upper_bound(map.classEnds.begin(), map.classEnds.end(), size_t(map.layout.triangle[r])) -
                                map.classEnds.begin());
        applyReceiverClass(set, r, map.classes[std::min(m, map.classes.size() - 1)]);
    }
}

/// A name safe in a file name: letters, digits, '-', '_' and '.' are kept, the rest become '_'.
std::string fileSafe(const std::string& name) {
    std::string safe;
    for (char c : name) safe += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.' ? c : '_';
    return safe.empty() || safe[0] == '.' ? "_" + safe : safe;
}

/// out/lightmap.exr -> out/lightmap-NAME.exr (or .png).
std::string derivedPath(const std::string& output, const std::string& name, const char* extension) {
    std::filesystem::path path(output);
    std::string stem = path.stem().string();
    return (path.parent_path() / (stem + "-" + name + extension)).string();
}

/// All meshes in one mesh (the atlas's receivers come from one rasterization); attributes that
/// some mesh lacks are dropped.
IndexedMesh concatenate(std::span<const IndexedMesh> meshes) {
    IndexedMesh all;
    bool normals = true;
    for (const IndexedMesh& mesh : meshes) normals &= mesh.normal.size() == mesh.position.size();
    for (const IndexedMesh& mesh : meshes) {
        const uint32_t base = uint32_t(all.position.size());
        all.position.insert(all.position.end(), mesh.position.begin(), mesh.position.end());
        if (normals) all.normal.insert(all.normal.end(), mesh.normal.begin(), mesh.normal.end());
        all.uv1.insert(all.uv1.end(), mesh.uv1.begin(), mesh.uv1.end());
        for (uint32_t i : mesh.indices) all.indices.push_back(base + i);
    }
    return all;
}

/// The parts of a map's surface that get no texel, one warning each: overlapping UVs, UVs
/// outside [0, 1]^2 (own UVs under "uv": "mesh" are used as they are, and a lightmap does not
/// wrap), and triangles with no UV area. Shares of the surface below 0.1 % are rounding at the
/// map's border and go unsaid.
std::vector<std::string> unbakedSurfaceWarnings(const Lightmap& map) {
    std::vector<std::string> out;
    const LightmapLayout& l = map.layout;
    if (l.overlapping > 0)
        out.push_back(fmt::format("{}: {} texels covered by more than one triangle (overlapping UVs; \"uv\": \"generate\" makes new ones)",
                                  map.label, l.overlapping));
    const double surface = l.surfaceArea > 0 ? l.surfaceArea : 1.0;
    if (l.outsideArea > 1e-3 * surface)
        out.push_back(fmt::format("{}: {:.1f} % of the surface has UVs outside [0, 1] and gets no texels (a lightmap does not wrap; "
                                  "\"uv\": \"generate\" makes new ones)",
                                  map.label, 100.0 * l.outsideArea / surface));
    if (l.noUvTriangles > 0 && l.noUvArea > 1e-3 * surface)
        out.push_back(fmt::format("{}: {} triangle{} ({:.1f} % of the surface) with no UV area get{} no texels (\"uv\": \"generate\" "
                                  "makes new ones)",
                                  map.label, l.noUvTriangles, l.noUvTriangles == 1 ? "" : "s", 100.0 * l.noUvArea / surface,
                                  l.noUvTriangles == 1 ? "s" : ""));
    return out;
}

class LightmapKind final : public ReceiverKind {
public:
    /// @param checked true when the meshes came from parseScene's check (loaded once per bake).
    LightmapKind(std::vector<Lightmap> maps, std::vector<Lightmap> atlasParts, LightmapSettings settings, bool checked)
        : maps_(std::move(maps)), parts_(std::move(atlasParts)), settings_(std::move(settings)), padding_(settings_.padding),
          meshesFromCheck_(checked) {}

    ReceiverSet receivers() override {
        if (!parts_.empty()) maps_.push_back(makeAtlas());
        ReceiverSet all;
        for (Lightmap& map : maps_) {
            map.layout = rasterizeLightmap(map.mesh, map.width, map.height);
            addPolygons(map, all.size());
            map.mesh = IndexedMesh{};  // the layout is all the writer needs
            for (std::string& warning : unbakedSurfaceWarnings(map)) {
                printWarning("{}", warning);
                warnings_.push_back(std::move(warning));
            }
            map.first = all.size();
            applyClasses(map);
            ReceiverSet& set = map.layout.receivers;
            if (!set.unshadowed.empty() || !all.unshadowed.empty()) {
                all.unshadowed.resize(all.size(), 0);
                if (set.unshadowed.empty()) set.unshadowed.assign(set.size(), 0);
                all.unshadowed.insert(all.unshadowed.end(), set.unshadowed.begin(), set.unshadowed.end());
            }
            all.position.insert(all.position.end(), set.position.begin(), set.position.end());
            all.normal.insert(all.normal.end(), set.normal.begin(), set.normal.end());
            set = ReceiverSet{};
        }
        texels_ = all.size();
        return all;
    }

    /// texels_per_unit beyond what a max_resolution square holds even packed perfectly: the packer
    /// would lower the density to fill that square, after minutes of bisection over thousands of
    /// charts, and the plan would then refuse the square if this machine cannot hold it
    /// (texels_per_unit 1e9 on a 6,000-triangle mesh: 7.5 minutes, then "needs 33 GiB"). That
    /// refusal now comes first.
    void checkDensityFits(const std::vector<IndexedMesh>& meshes) const {
        if (!(settings_.density > 0)) return;
        double area = 0;
        for (const IndexedMesh& mesh : meshes) area += surfaceArea(mesh);
        const double square = double(settings_.maxSide) * double(settings_.maxSide);
        if (!(area * settings_.density * settings_.density > square)) return;
        const std::string what = fmt::format("a lightmap at texels_per_unit {} ({:.3g} texels for {:.3g} square units of "
                                             "surface, more than a {}x{} atlas holds: the density would be lowered to fill one)",
                                             settings_.density, area * settings_.density * settings_.density, area,
                                             settings_.maxSide, settings_.maxSide);
        checkMemoryFits(settings_.where, what.c_str(), uint64_t(square) * (kBytesPerTexel + 64));
    }

    /// Every texel of every map, when the sizes are known before the scan: the per-mesh maps', and
    /// an atlas of a given resolution (one sized by texels_per_unit is sized by its packing).
    std::optional<uint64_t> receiverBound() const override {
        if (!parts_.empty() && settings_.density > 0) return std::nullopt;
        uint64_t texels = parts_.empty() ? 0 : uint64_t(settings_.width) * uint64_t(settings_.height);
        for (const Lightmap& map : maps_) texels += uint64_t(map.width) * uint64_t(map.height);
        return texels;
    }

    /// What a lightmap holds per texel beyond what the plan counts for every receiver: the
    /// rasterized layout (texel, polygon and receiver per covered texel), its receivers until they
    /// are copied into the bake's set, and the receiver polygons. Measured: peak RSS grew by 203
    /// bytes per texel from a 1024² to a 2048² atlas (examples/lightmap.json), of which the plan
    /// counted 60; without this a 4096² lightmap overran --memory-budget by two thirds.
    static constexpr uint64_t kBytesPerTexel = 144;
    uint64_t maxResidentBytes(uint64_t receivers, std::optional<uint64_t>) const override { return receivers * kBytesPerTexel; }
    uint64_t residentBytes() const override { return texels_ * kBytesPerTexel; }

    const ReceiverPolygons* receiverPolygons() const override { return &polygons_; }

    std::vector<std::string> outputFiles(const std::string& output) const override {
        std::vector<std::string> files;
        for (const Lightmap& map : maps_)
            files.push_back(derivedPath(output, map.name, ".exr")), files.push_back(derivedPath(output, map.name, ".png"));
        if (!atlasMeshes_.empty()) files.push_back(derivedPath(output, "uv1", ".glb"));
        return files;
    }

    void write(const OutputContext& c) override {
        outputs_.clear();
        for (const Lightmap& map : maps_) writeMap(c, map);
        if (!atlasMeshes_.empty()) {
            const std::string gltf = derivedPath(c.output, "uv1", ".glb");
            writeLightmapGltf(gltf, atlasMeshes_, std::filesystem::path(derivedPath(c.output, "atlas", ".exr")).filename().string());
            outputs_.push_back(gltf);
        }
    }

    nlohmann::json stats() const override {
        nlohmann::json maps = nlohmann::json::array();
        for (const Lightmap& map : maps_) {
            const uint64_t texels = uint64_t(map.width) * uint64_t(map.height);
            maps.push_back({{"name", map.name}, {"width", map.width}, {"height", map.height},
                            {"covered_texels", map.layout.texel.size()},
                            {"utilisation", texels ? double(map.layout.texel.size()) / double(texels) : 0.0},
                            {"generated_uvs", map.name == kAtlasName && !atlasMeshes_.empty()}});
        }
        nlohmann::json lightmap = {{"maps", maps}};
        if (!atlasMeshes_.empty()) lightmap["atlas"] = atlasStats_;
        lightmap["meshes_loaded_by"] = meshesFromCheck_ ? "scene check" : "bake";
        nlohmann::json stats = {{"lightmap", lightmap}, {"outputs", outputs_}};
        if (!warnings_.empty()) stats["warnings"] = warnings_;  // the bake's own are added to them
        return stats;
    }

private:
    uint64_t texels_ = 0;  ///< receivers made, for residentBytes()
    /// The mesh's triangles as receiver polygons (--method hh), and each receiver's polygon and texel.
    void addPolygons(const Lightmap& map, size_t firstReceiver) {
        const std::vector<glm::vec2>& uv = *lightmapUvs(map.mesh);
        const uint32_t first = uint32_t(polygons_.polygons.size());
        for (size_t t = 0; t < map.mesh.triangleCount(); ++t) {
            ReceiverPolygon p;
            for (int k = 0; k < 3; ++k) {
                const uint32_t i = map.mesh.indices[3 * t + k];
                p.position[k] = glm::dvec3(map.mesh.position[i]);
                p.texel[k] = glm::dvec2(uv[i]) * glm::dvec2(map.width, map.height);
            }
            polygons_.polygons.push_back(p);
        }
        polygons_.polygonOf.resize(firstReceiver), polygons_.texelOf.resize(firstReceiver);
        for (size_t k = 0; k < map.layout.texel.size(); ++k) {
            polygons_.polygonOf.push_back(first + map.layout.triangle[k]);
            polygons_.texelOf.push_back({int(map.layout.texel[k] % uint32_t(map.width)), int(map.layout.texel[k] / uint32_t(map.width))});
        }
    }

    void writeMap(const OutputContext& c, const Lightmap& map) {
        const LightmapLayout& layout = map.layout;
        const size_t texels = size_t(map.width) * map.height;
        std::vector<float> V(texels, 0.f), ER(texels, 0.f), EG(texels, 0.f), EB(texels, 0.f);
        std::vector<uint8_t> filled(texels, 0);
        for (size_t k = 0; k < layout.texel.size(); ++k) {
            const size_t r = map.first + k, t = layout.texel[k];
            const glm::vec3& e = c.results.irradiance[r];
            V[t] = c.results.visibility[r], ER[t] = e.x, EG[t] = e.y, EB[t] = e.z;
            filled[t] = 1;
        }
        // Dilation gives bilinear lookups across UV seams baked values instead of black; A keeps
        // the true coverage, so an engine can still tell surface from padding.
        std::vector<float>* dilated[] = {&V, &ER, &EG, &EB};
        dilateLightmap(dilated, filled, map.width, map.height, padding_);

        // R, G, B, A drop into an engine as a lightmap texture; V (and the irradiance, when RGB
        // holds V) are the extra passes.
        const bool grey = c.scene.exr.colour == ExrColour::Visibility;
        std::vector<ExrChannel> channels = {{"R", (grey ? V : ER).data()}, {"G", (grey ? V : EG).data()},
                                            {"B", (grey ? V : EB).data()}, {"A", layout.coverage.data()},
                                            {"visibility.V", V.data()}};
        if (grey) channels.insert(channels.end(), {{"irradiance.R", ER.data()}, {"irradiance.G", EG.data()}, {"irradiance.B", EB.data()}});
        std::vector<ExrAttribute> attributes = bakeAttributes(c.scene, c.samples, c.scene.exr.colour);
        attributes.insert(attributes.end(), {{"penumbra:receivers", std::string("lightmap")},
                                             {"penumbra:mesh", map.source},
                                             {"penumbra:meshName", map.name},
                                             {"penumbra:padding", padding_},
                                             {"penumbra:texels", int(layout.texel.size())}});
        const std::string exr = derivedPath(c.output, map.name, ".exr");
        ensureParentDirectory(exr);
        writeExr(exr, map.width, map.height, channels, attributes, c.scene.exr.format);
        writePreview(derivedPath(c.output, map.name, ".png"), map, ER, EG, EB, filled);
        outputs_.push_back(exr);
        outputs_.push_back(derivedPath(c.output, map.name, ".png"));
    }

    /// Cuts and packs the meshes without usable UVs into one atlas, which becomes one more map.
    Lightmap makeAtlas() {
        std::vector<IndexedMesh> meshes;
        std::string sources, labels;
        Lightmap map;
        for (Lightmap& part : parts_) {
            map.classes.push_back(part.receiverClass);
            meshes.push_back(std::move(part.mesh));
            sources += (sources.empty() ? "" : ", ") + part.source;
            labels += (labels.empty() ? "" : ", ") + part.label;
        }
        AtlasOptions options;
        options.coneDeg = settings_.chartDeg;
        options.pack.padding = settings_.padding;
        options.pack.texelsPerUnit = settings_.density;
        options.pack.width = settings_.width, options.pack.height = settings_.height;
        options.pack.maxSide = settings_.maxSide, options.pack.powerOfTwo = settings_.powerOfTwo;
        options.quiet = quiet();
        checkDensityFits(meshes);
        const Stopwatch watch;
        LightmapAtlas atlas = buildLightmapAtlas(meshes, options);
        const double seconds = watch.seconds();
        if (atlas.width == 0)
            fail(settings_.where, "the {} charts of {} do not fit a {}x{} atlas with padding {} (use a larger resolution or a smaller padding)",
                 atlas.charts, labels, settings_.density > 0 ? settings_.maxSide : settings_.width,
                 settings_.density > 0 ? settings_.maxSide : settings_.height, settings_.padding);
        if (atlas.densityLowered)
            fmt::print(stderr, "penumbra: warning: {}: texels_per_unit {} needs an atlas larger than {}x{}; baking at {:.4g} instead\n",
                       settings_.where, settings_.density, settings_.maxSide, settings_.maxSide, atlas.texelsPerUnit);
        atlasStats_ = {{"width", atlas.width}, {"height", atlas.height}, {"charts", atlas.charts},
                       {"texels_per_unit", atlas.texelsPerUnit}, {"density_lowered", atlas.densityLowered},
                       {"padding", settings_.padding}, {"meshes", parts_.size()}, {"build_time_s", seconds},
                       {"mean_stretch", atlas.meanStretch}, {"max_stretch", atlas.maxStretch}};
        map.source = sources, map.label = "lightmap atlas (" + labels + ")", map.name = kAtlasName;
        map.width = atlas.width, map.height = atlas.height;
        for (const IndexedMesh& mesh : atlas.meshes)  // the atlas's meshes are the parts, in order
            map.classEnds.push_back((map.classEnds.empty() ? 0 : map.classEnds.back()) + mesh.triangleCount());
        map.mesh = concatenate(atlas.meshes);
        atlasMeshes_ = std::move(atlas.meshes);
        for (size_t m = 0; m < atlasMeshes_.size(); ++m) atlasMeshes_[m].name = parts_[m].name;
        parts_.clear();
        return map;
    }

    /// The irradiance, exposed so that the 99th percentile of the baked texels' luminance sits
    /// near white; texels with no value (beyond the padding) are a neutral dark grey.
    void writePreview(const std::string& path, const Lightmap& map, const std::vector<float>& r,
                      const std::vector<float>& g, const std::vector<float>& b, const std::vector<uint8_t>& filled) const {
        std::vector<float> luminance;
        for (uint32_t t : map.layout.texel) luminance.push_back(0.2126f * r[t] + 0.7152f * g[t] + 0.0722f * b[t]);
        float white = 1.f;
        if (!luminance.empty()) {
            size_t q = std::min(luminance.size() - 1, size_t(0.99 * double(luminance.size())));
            std::nth_element(luminance.begin(), luminance.begin() + q, luminance.end());
            white = luminance[q] > 0 ? luminance[q] : 1.f;
        }
        const float exposure = 0.92f / white;
        const size_t texels = filled.size();
        std::vector<uint8_t> rgb(texels * 3);
        for (size_t t = 0; t < texels; ++t) {
            if (!filled[t]) {
                rgb[3 * t] = rgb[3 * t + 1] = rgb[3 * t + 2] = encodeSrgb(0.02f);
                continue;
            }
            rgb[3 * t] = encodeSrgb(exposure * r[t]);
            rgb[3 * t + 1] = encodeSrgb(exposure * g[t]);
            rgb[3 * t + 2] = encodeSrgb(exposure * b[t]);
        }
        writePng8(path, map.width, map.height, 3, rgb);
    }

    std::vector<Lightmap> maps_;
    std::vector<std::string> warnings_;  ///< unbakedSurfaceWarnings() of every map, for the stats
    std::vector<Lightmap> parts_;  ///< meshes waiting for the atlas (until receivers())
    LightmapSettings settings_;
    int padding_;
    std::vector<IndexedMesh> atlasMeshes_;  ///< the atlas's meshes with their generated uv1
    nlohmann::json atlasStats_;
    std::vector<std::string> outputs_;      ///< files written
    ReceiverPolygons polygons_;             ///< --method hh: the maps' triangles and texels
    bool meshesFromCheck_ = false;          ///< the meshes were parseScene's (ValidatedMaps)
};

/// The reader for entry @p g's file @p file: its type chooses it, as for the blocker stream (an
/// OBJ may be called mesh.txt); a "file" entry's extension. nullopt: neither says a mesh.
std::optional<GeometryFormat> meshFormat(const GeometryDesc& g, const std::string& file) {
    if (g.type == "obj") return GeometryFormat::Obj;
    if (g.type == "gltf" || g.type == "glb") return GeometryFormat::Gltf;
    const std::optional<GeometryFormat> format = geometryFormatOf(file);
    return format == GeometryFormat::Ptri ? std::nullopt : format;
}

/// The file behind geometry entry @p index, which must be an obj/gltf/glb file.
std::string meshFile(const JsonParams& j, const SceneDesc& scene, size_t slot, size_t index) {
    const std::string key = fmt::format("meshes[{}]", slot);
    const GeometryDesc& g = scene.geometry[index];
    const nlohmann::json* path = g.params.is_object() && g.params.contains("path") ? &g.params["path"] : nullptr;
    if (!path || !path->is_string())
        fail(j.where(key), "{} is a \"{}\" entry, not a mesh file (obj, gltf or glb)", g.path, g.type);
    std::string file = resolveScenePath(scene.baseDir, path->get<std::string>());
    if (!meshFormat(g, file))
        fail(j.where(key), "{} ({}) is not an obj, gltf or glb file", g.path, file);
    return file;
}

/// The size, padding and UV keys.
LightmapSettings parseSettings(const JsonParams& j) {
    LightmapSettings settings;
    settings.where = j.where();
    const nlohmann::json* resolution = j.raw("resolution");
    const nlohmann::json* perUnit = j.raw("texels_per_unit");
    if (resolution && resolution->is_null()) resolution = nullptr;
    if (perUnit && perUnit->is_null()) perUnit = nullptr;
    if (resolution && perUnit) fail(j.where("texels_per_unit"), "give either resolution or texels_per_unit, not both");
    if (resolution) {
        auto side = [&](const nlohmann::json& x) {
            if (!x.is_number_integer() || x.get<int64_t>() < 1 || x.get<int64_t>() > kMaxSide)
                fail(j.where("resolution"), "expected an integer in [1, {}] or [width, height] of such, got {}",
                     kMaxSide, resolution->dump());
            return int(x.get<int64_t>());
        };
        if (resolution->is_array() && resolution->size() == 2)
            settings.width = side((*resolution)[0]), settings.height = side((*resolution)[1]);
        else
            settings.width = settings.height = side(*resolution);
    }
    if (perUnit) {
        settings.density = perUnit->is_number() ? perUnit->get<double>() : 0.0;
        if (!(settings.density > 0) || !std::isfinite(settings.density))
            fail(j.where("texels_per_unit"), "expected a positive number, got {}", perUnit->dump());
    }
    settings.padding = int(j.integer("padding", 4, 0, 1024));
    const std::string uv = j.string("uv", "auto");
    if (uv == "auto") settings.uv = UvSource::Auto;
    else if (uv == "mesh") settings.uv = UvSource::Mesh;
    else if (uv == "generate") settings.uv = UvSource::Generate;
    else fail(j.where("uv"), "expected \"auto\", \"mesh\" or \"generate\", got \"{}\"", uv);
    auto angle = [&](const char* key, double fallback, double lo, double hi) {
        const double x = j.number(key, fallback);
        if (!(x >= lo && x <= hi)) fail(j.where(key), "expected an angle in [{}, {}] degrees, got {}", lo, hi, x);
        return x;
    };
    settings.creaseDeg = angle("crease_angle_deg", kDefaultCreaseAngleDeg, 0, 180);
    settings.chartDeg = angle("chart_angle_deg", kDefaultChartConeDeg, 1, 80);
    settings.powerOfTwo = j.boolean("power_of_two", false);
    settings.maxSide = int(j.integer("max_resolution", kMaxSide, 1, kMaxSide));
    // They shape the size texels_per_unit chooses; with a fixed resolution they would do nothing
    // (as texels_per_unit with resolution is refused above).
    if (resolution)
        for (const char* key : {"power_of_two", "max_resolution"})
            if (j.has(key)) fail(j.where(key), "applies to texels_per_unit, not to a fixed \"resolution\"; give one or the other");
    return settings;
}

/// The per-mesh map's size from the density, for a mesh that keeps its own UVs.
void sizeFromDensity(const JsonParams& j, const std::string& key, const LightmapSettings& settings, Lightmap& map) {
    const int64_t side = lightmapSideForDensity(map.mesh, settings.density);
    if (side == 0) fail(j.where(key), "{}: every UV triangle is degenerate", map.label);
    if (side > kMaxSide)
        fail(j.where("texels_per_unit"), "{} gives {} a {}x{} lightmap (at most {})", settings.density, map.label, side,
             side, kMaxSide);
    map.width = map.height = int(side);
}

/// The maps the factory made from "receivers": per-mesh ones, and meshes waiting for the atlas.
struct LightmapMaps {
    std::vector<Lightmap> maps, atlasParts;
};

/// What the maps depend on: the "receivers" object, each named entry as written, and the
/// identity (size and modification time) of each entry's file.
std::string mapsKey(const SceneDesc& scene, const std::vector<size_t>& meshes, const std::vector<std::string>& files) {
    std::string key = scene.baseDir.string() + '\n' + scene.receivers.dump();
    for (size_t slot = 0; slot < meshes.size(); ++slot) {
        const GeometryDesc& g = scene.geometry[meshes[slot]];
        key += '\n' + g.params.dump() + fmt::format(" {} {}", g.receiveShadows, g.receiverOffset);
        const glm::mat4 m = g.transform.matrix();
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r) key += fmt::format(" {}", m[c][r]);
        std::error_code ec;
        key += fmt::format(" {} {}", std::filesystem::file_size(files[slot], ec),
                           std::filesystem::last_write_time(files[slot], ec).time_since_epoch().count());
    }
    return key;
}

/// @brief The maps parseScene made to check the meshes, handed to the bake of the same scene
/// so that every mesh is loaded once: parseScene's check needs the meshes (their UVs, their
/// size at texels_per_unit), and the bake follows it. One entry, replaced by the next check and
/// taken (moved out) by the bake whose key matches.
class ValidatedMaps {
public:
    void put(std::string key, LightmapMaps maps) {
        std::lock_guard lock(mutex_);
        key_ = std::move(key), maps_ = std::move(maps), full_ = true;
    }
    std::optional<LightmapMaps> take(const std::string& key) {
        std::lock_guard lock(mutex_);
        if (!full_ || key != key_) return std::nullopt;
        full_ = false, key_.clear();
        return std::move(maps_);
    }

private:
    std::mutex mutex_;
    std::string key_;
    LightmapMaps maps_;
    bool full_ = false;
};

ValidatedMaps& validatedMaps() {
    static ValidatedMaps maps;
    return maps;
}

/// Loads the meshes of "meshes" and makes their maps, checking every one.
LightmapMaps makeMaps(const JsonParams& j, const SceneDesc& scene, const std::vector<size_t>& meshes,
                      const std::vector<std::string>& files, const LightmapSettings& settings) {
    LightmapMaps out;
    std::set<std::string> names{kAtlasName};
    for (size_t slot = 0; slot < meshes.size(); ++slot) {
        const std::string key = fmt::format("meshes[{}]", slot);
        const size_t index = meshes[slot];
        const std::string& file = files[slot];
        const GeometryDesc& geometry = scene.geometry[index];
        // The entry's OBJ "parts" pick its o/g groups here too: one lightmap mesh per group.
        const std::vector<std::string> parts = geometryParts(JsonParams(geometry.params, scene.file, geometry.path));
        std::vector<IndexedMesh> loaded = loadIndexedMeshes(file, geometry.transform.matrix(), parts, meshFormat(geometry, file));
        if (loaded.empty()) fail(j.where(key), "{} has no triangle meshes", file);
        for (size_t m = 0; m < loaded.size(); ++m) {
            Lightmap map;
            map.receiverClass = scene.receiverClasses[geometry.receiverClass];
            map.source = file;
            map.label = loaded.size() == 1 ? file : fmt::format("{} (mesh \"{}\")", file, loaded[m].name);
            if (settings.uv == UvSource::Mesh && !lightmapUvs(loaded[m]))
                fail(j.where(key), "{} has no texture coordinates (needs OBJ vt, or glTF TEXCOORD_0/TEXCOORD_1; \"uv\": \"auto\" generates them)",
                     map.label);
            // The mesh's own name when it has one, else its position in "meshes".
            std::string base = loaded[m].name.empty() ? std::to_string(index) : fileSafe(loaded[m].name);
            if (loaded[m].name.empty() && loaded.size() > 1) base += "-" + std::to_string(m);
            std::string name = base;
            for (int n = 2; names.count(name); ++n) name = base + "-" + std::to_string(n);
            names.insert(name);
            map.name = name;
            const bool generate = settings.uv == UvSource::Generate || (settings.uv == UvSource::Auto && !usableLightmapUvs(loaded[m]));
            map.mesh = loaded[m].normal.empty() ? withCreaseNormals(loaded[m], settings.creaseDeg) : std::move(loaded[m]);
            map.width = settings.width, map.height = settings.height;
            if (generate) {
                out.atlasParts.push_back(std::move(map));
                continue;
            }
            if (settings.density > 0) sizeFromDensity(j, key, settings, map);
            out.maps.push_back(std::move(map));
        }
    }
    return out;
}

std::unique_ptr<ReceiverKind> makeLightmapKind(const JsonParams& j, const SceneDesc& scene, KindUse use) {
    requireOutputExtension(scene, {".exr"}, "lightmap");
    const std::vector<size_t> meshes = geometryIndices(j, "meshes", scene);  // each once
    const LightmapSettings settings = parseSettings(j);
    std::vector<std::string> files;  // each entry's mesh file, checked once
    for (size_t slot = 0; slot < meshes.size(); ++slot) files.push_back(meshFile(j, scene, slot, meshes[slot]));
    const std::string key = mapsKey(scene, meshes, files);
    if (use == KindUse::Validate) {
        validatedMaps().put(key, makeMaps(j, scene, meshes, files, settings));
        return nullptr;
    }
    std::optional<LightmapMaps> made = validatedMaps().take(key);
    const bool checked = made.has_value();
    if (!made) made = makeMaps(j, scene, meshes, files, settings);
    return std::make_unique<LightmapKind>(std::move(made->maps), std::move(made->atlasParts), settings, checked);
}

}  // namespace

namespace {
const ReceiverKindRegistration kLightmap{"lightmap", &makeLightmapKind};
}  // namespace

}  // namespace penumbra
