#include "bake/Scene.h"

#include "bake/cast/Caster.h"
#include "bake/kinds/ReceiverKind.h"
#include "bake/SceneAlpha.h"
#include "bake/shading/ReceiverShading.h"
#include "bake/light/SunLight.h"
#include "stream/util/CheckedMath.h"
#include "stream/util/Error.h"
#include "stream/GeometryFile.h"
#include "stream/util/JsonParams.h"
#include "stream/SourceRegistry.h"
#include "stream/Translucency.h"

#include <algorithm>
#include <utility>
#include <cmath>

namespace penumbra {
namespace {

std::string indexed(const std::string& key, size_t i) { return key + "[" + std::to_string(i) + "]"; }

/// An RGB value given as [r, g, b] or as one number for grey; must be finite and non-negative.
glm::dvec3 colour(const JsonParams& j, const std::string& key, const glm::dvec3& fallback) {
    const nlohmann::json* raw = j.raw(key);
    glm::dvec3 c = raw && raw->is_number() ? glm::dvec3(j.number(key)) : j.vec3(key, fallback);
    for (int i = 0; i < 3; ++i)
        if (!(c[i] >= 0) || !std::isfinite(c[i])) fail(j.where(key), "must be finite and non-negative, got {}", c[i]);
    return c;
}

LightDesc parseLight(const JsonParams& j) {
    LightDesc l;
    l.where = j.where();
    std::string type = j.string("type");
    if (type == "rect") {
        l.type = LightType::Rect;
        l.center = j.vec3("center"), l.u = j.vec3("u"), l.v = j.vec3("v");
    } else if (type == "disk") {
        l.type = LightType::Disk;
        l.center = j.vec3("center"), l.normal = j.vec3("normal"), l.radius = j.number("radius");
    } else if (type == "sphere") {
        l.type = LightType::Sphere;
        l.center = j.vec3("center"), l.radius = j.number("radius");
    } else if (type == "polygon") {
        l.type = LightType::Polygon;
        const nlohmann::json* pts = j.raw("vertices");
        if (!pts) j.missing("vertices");
        if (!pts->is_array()) fail(j.where("vertices"), "expected an array of [x, y, z] points");
        for (size_t i = 0; i < pts->size(); ++i) {
            nlohmann::json wrapper = {{"p", (*pts)[i]}};
            l.polygon.push_back(JsonParams(wrapper, j.file(), j.path(indexed("vertices", i))).vec3("p"));
        }
    } else if (type == "sun") {
        l.type = LightType::Sun;
        l.direction = j.vec3("direction");
        l.angularDiameterDeg = j.number("angular_diameter_deg", l.angularDiameterDeg);
        if (j.has("irradiance") && j.has("radiance"))
            fail(j.where("irradiance"), "give either \"irradiance\" or \"radiance\", not both");
        if (j.has("radiance")) l.irradiance = sunIrradianceFromRadiance(colour(j, "radiance", glm::dvec3(0.0)), l.angularDiameterDeg);
        else l.irradiance = colour(j, "irradiance", l.irradiance);
    } else {
        fail(j.where("type"), "unknown light type \"{}\" (known: rect, disk, sphere, polygon, sun)", type);
    }
    if (l.type != LightType::Sun) {
        if (j.has("power") && j.has("radiance")) fail(j.where("power"), "give either \"power\" or \"radiance\", not both");
        l.radiance = colour(j, "radiance", l.radiance);
    }
    l.samples = int(j.integer("samples", l.samples, 1, 65536));
    l.sampleSets = int(j.integer("sample_sets", l.sampleSets, 1, 256));
    validateLight(l);
    flattenPolygon(l);
    // Power needs the light's area, so it is converted after the shape is known to be valid.
    if (l.type == LightType::Sun && j.has("power")) fail(j.where("power"), "a sun takes \"irradiance\" or \"radiance\", not \"power\"");
    if (j.has("power")) l.radiance = radianceFromPower(l, colour(j, "power", glm::dvec3(0.0)));
    j.finish();
    return l;
}

void parseOptions(const JsonParams& j, SceneDesc& scene) {
    CastOptions& o = scene.options;
    // The switches: each key a boolean member of CastOptions (docs/scene-format.md, "bake").
    static constexpr std::pair<const char*, bool CastOptions::*> kSwitches[] = {
        {"umbra_bits", &CastOptions::umbraBits},       {"active_planes", &CastOptions::activePlanes},
        {"lazy_volumes", &CastOptions::lazyVolumes},   {"lazy_masks", &CastOptions::lazyMasks},
        {"rebuild", &CastOptions::rebuild},            {"sort_blockers", &CastOptions::sortBlockers},
        {"sample_table", &CastOptions::sampleTable},   {"closed_casters", &CastOptions::closedCasters},
        {"embree_rule_filter", &CastOptions::embreeRuleFilter}, {"cull_before_spill", &CastOptions::cullBeforeSpill},
    };
    for (const auto& [key, member] : kSwitches) o.*member = j.boolean(key, o.*member);
    o.sampleTableAngles = int(j.integer("sample_table_angles", o.sampleTableAngles, 4, 4096));
    o.sampleTableOffsets = int(j.integer("sample_table_offsets", o.sampleTableOffsets, 1, 4096));
    o.rebuildThreshold = j.number("rebuild_threshold", o.rebuildThreshold);
    if (!(o.rebuildThreshold > 0 && o.rebuildThreshold <= 1))
        fail(j.where("rebuild_threshold"), "must be in (0, 1], got {}", o.rebuildThreshold);
    o.hierarchy.leafSize = int(j.integer("leaf_size", o.hierarchy.leafSize, 1, 4096));
    o.hierarchy.medianSplitAbove = int(j.integer("median_split_above", o.hierarchy.medianSplitAbove, 1, 1 << 30));
    o.groupSize = int(j.integer("group_size", o.groupSize, 1, 64));
    o.epsilon = j.number("epsilon", o.epsilon);
    // Beyond a tenth of the scene's scale the receiver-end margin would hide most shadows.
    if (!(o.epsilon >= 0 && o.epsilon <= kMaxEpsilon))
        fail(j.where("epsilon"), "must be in 0..{}, got {}", kMaxEpsilon, o.epsilon);
    if (j.has("simd")) o.simd = parseSimdLevel(j.string("simd"), j.where("simd"));
    scene.seed = j.seed("seed", scene.seed);
    scene.smoothShading = j.boolean("smooth_shading", scene.smoothShading);
    // Every method's own keys are read (and checked) by the method, whichever one bakes.
    for (const std::string& name : casterNames())
        if (const auto& check = casterEntry(name).checkOptions) check(j);
    j.finish();
}

/// The receiver class of @p c, added to the scene's list when new.
uint32_t receiverClassIndex(SceneDesc& scene, const ReceiverClass& c, const std::string& where) {
    for (size_t i = 0; i < scene.receiverClasses.size(); ++i)
        if (scene.receiverClasses[i] == c) return uint32_t(i);
    if (scene.receiverClasses.size() > kTriangleClassMax)
        fail(where, "at most {} different pairs of receive_shadows and receiver_offset in one scene", kTriangleClassMax);
    scene.receiverClasses.push_back(c);
    return uint32_t(scene.receiverClasses.size() - 1);
}

/// An entry's "translucent": {"color": [r, g, b], "opacity": a}: a stained filter covering the
/// fraction a, t = (1 - a) + a color (stream/Translucency.h, surfaceTransmittance).
void parseTranslucent(const JsonParams& g, GeometryDesc& desc) {
    if (!g.has("translucent")) return;
    const nlohmann::json* raw = g.raw("translucent");
    if (!raw->is_object()) fail(g.where("translucent"), "expected an object with \"color\" and \"opacity\"");
    JsonParams t(*raw, g.file(), g.path("translucent"));
    const glm::dvec3 color = t.vec3("color", glm::dvec3(1.0));
    for (int c = 0; c < 3; ++c) checkUnitInterval(color[c], t.where("color") + "[" + std::to_string(c) + "]");
    const double opacity = t.number("opacity", 1.0);
    checkUnitInterval(opacity, t.where("opacity"));
    t.finish();
    if (desc.maxDistance) fail(g.where("translucent"), "cannot be combined with max_distance");
    desc.translucentId = translucentId(surfaceTransmittance(color, opacity, 1.0), g.where("translucent"));
}

/// The per-object controls of a geometry entry (docs/scene-format.md, "Per-object controls").
void parseObjectControls(const JsonParams& g, GeometryDesc& desc, SceneDesc& scene) {
    desc.castShadows = g.boolean("cast_shadows", true);
    desc.receiveShadows = g.boolean("receive_shadows", true);
    desc.receiverOffset = g.number("receiver_offset", 0.0);
    if (!std::isfinite(desc.receiverOffset)) fail(g.where("receiver_offset"), "must be a finite number, got {}", desc.receiverOffset);
    if (g.has("max_distance")) {
        const double d = g.number("max_distance");
        if (!(d > 0.0) || !std::isfinite(d)) fail(g.where("max_distance"), "must be a finite number > 0, got {}", d);
        desc.maxDistance = d;
    }
    desc.receiverClass = receiverClassIndex(scene, {desc.receiveShadows, desc.receiverOffset}, g.where("receiver_offset"));
    parseTranslucent(g, desc);
}

/// A generator's "leaf_texture" (tree, forest) or "petal_texture" (flowers) and "alpha_cutoff".
void parseOutlineTexture(const JsonParams& g, const GeometryDesc& desc, size_t index, SceneDesc& scene,
                         std::vector<SceneOutlineTexture>& textures) {
    const bool trees = desc.type == "tree" || desc.type == "forest", flowers = desc.type == "flowers";
    for (const char* key : {"leaf_texture", "petal_texture", "alpha_cutoff"})
        if (g.has(key) && !(trees && std::string(key) != "petal_texture") && !(flowers && std::string(key) != "leaf_texture"))
            fail(g.where(key), "is not an option of a \"{}\" entry (leaf_texture: tree, forest; petal_texture: flowers)", desc.type);
    const char* key = trees ? "leaf_texture" : "petal_texture";
    if (!g.has(key)) {
        if (g.has("alpha_cutoff")) fail(g.where("alpha_cutoff"), "needs \"{}\"", key);
        return;
    }
    if (desc.maxDistance) fail(g.where(key), "cannot be combined with max_distance");
    SceneOutlineTexture t;
    t.geometry = index, t.key = g.where(key), t.petal = flowers;
    t.path = resolveScenePath(scene.baseDir, g.string(key), t.key);
    t.cutoff = g.number("alpha_cutoff", t.cutoff);
    checkUnitInterval(t.cutoff, g.where("alpha_cutoff"));
    textures.push_back(std::move(t));
}

/// A table with every entry's max_distance ids (AlphaTable::withDistance), when one has it.
std::shared_ptr<AlphaTable> addDistanceIds(SceneDesc& scene) {
    std::shared_ptr<AlphaTable> table;
    for (GeometryDesc& g : scene.geometry) {
        if (!g.maxDistance) continue;
        if (!table) table = std::make_shared<AlphaTable>();
        for (uint32_t a = 0; a < kBuiltinAlphaCount; ++a) g.distanceIds[a] = table->withDistance(a, *g.maxDistance);
    }
    return table;
}

/// Replaces the built-in alpha ids of an entry's triangles: alpha id a becomes ids[a] (its
/// max_distance ids, GeometryDesc::distanceIds, or a generator's texture ids, sceneOutlineIds()).
/// A glTF file's own alpha ids already hold the distance (SceneAlpha.h) and pass unchanged.
class BuiltinIdSource final : public DecoratedSource {
public:
    BuiltinIdSource(TriangleSourcePtr inner, const std::array<uint32_t, kBuiltinAlphaCount>& ids, std::string where, bool ownIds)
        : DecoratedSource(std::move(inner)), ids_(ids), where_(std::move(where)), ownIds_(ownIds) {}
    size_t read(std::span<Triangle> out) override {
        const size_t n = inner_->read(out);
        for (size_t i = 0; i < n; ++i) {
            const uint32_t id = alphaIdOf(out[i].flags);
            if (id >= kBuiltinAlphaCount && ownIds_) continue;
            if (id >= kBuiltinAlphaCount) fail(where_, "is not supported on triangles with an alpha texture of their own");
            out[i].flags = withAlphaId(out[i].flags, ids_[id]);
        }
        return n;
    }
    /// One triangle out for one in: a skip is the inner source's.
    uint64_t skip(uint64_t count) override { return inner_->skip(count); }

private:
    std::array<uint32_t, kBuiltinAlphaCount> ids_;
    std::string where_;
    bool ownIds_;
};

/// Gives an entry's triangles its translucent id; a cut-out triangle cannot also be translucent.
class TranslucentIdSource final : public DecoratedSource {
public:
    TranslucentIdSource(TriangleSourcePtr inner, uint32_t id, std::string where)
        : DecoratedSource(std::move(inner)), id_(id), where_(std::move(where)) {}
    size_t read(std::span<Triangle> out) override {
        const size_t n = inner_->read(out);
        for (size_t i = 0; i < n; ++i) {
            if (alphaIdOf(out[i].flags)) fail(where_, "is not supported on cut-out (alpha-tested) triangles");
            out[i].flags = withAlphaId(out[i].flags, id_);
        }
        return n;
    }
    uint64_t skip(uint64_t count) override { return inner_->skip(count); }

private:
    uint32_t id_;
    std::string where_;
};

/// The entry's source with its controls' marks: kTriangleNoCast, the receiver class, the
/// max_distance ids; for an export only the first, as the others mean something only with this
/// scene's receiver classes and alpha table.
TriangleSourcePtr withObjectControls(TriangleSourcePtr source, const GeometryDesc& g, const std::string& file, bool exporting,
                                     bool ownIds) {
    const uint32_t cls = exporting ? 0u : g.receiverClass << kTriangleClassShift;
    const uint32_t set = (g.castShadows ? 0u : uint32_t(kTriangleNoCast)) | cls;
    // A .ptri keeps the receiver classes of the scene that wrote it, which mean nothing here.
    if (set || g.type == "ptri" || g.type == "file") source = std::make_unique<FlagSource>(std::move(source), set, kTriangleClassMax << kTriangleClassShift);
    if (g.maxDistance && !exporting) source = std::make_unique<BuiltinIdSource>(std::move(source), g.distanceIds, file + ": " + g.path + ".max_distance", ownIds);
    if (g.translucentId && !exporting)
        source = std::make_unique<TranslucentIdSource>(std::move(source), *g.translucentId, file + ": " + g.path + ".translucent");
    return source;
}

}  // namespace

std::vector<std::string> geometryParts(const JsonParams& entry) {
    std::vector<std::string> parts;
    const nlohmann::json* raw = entry.raw("parts");
    if (!raw) return parts;
    if (!raw->is_array() || raw->empty()) fail(entry.where("parts"), "expected a non-empty array of o/g group names");
    for (const nlohmann::json& name : *raw) {
        if (!name.is_string()) fail(entry.where("parts"), "expected a non-empty array of o/g group names");
        parts.push_back(name.get<std::string>());
    }
    return parts;
}

std::vector<size_t> geometryIndices(const JsonParams& j, const std::string& key, const SceneDesc& scene) {
    const nlohmann::json* list = j.raw(key);
    if (!list) fail(j.where(key), "missing (a list of indices into \"geometry\")");
    if (!list->is_array() || list->empty()) fail(j.where(key), "expected a non-empty array of indices into \"geometry\"");
    std::vector<size_t> indices;
    for (size_t i = 0; i < list->size(); ++i) {
        const nlohmann::json& value = (*list)[i];
        const std::string where = fmt::format("{}[{}]", j.where(key), i);
        if (!value.is_number_integer()) fail(where, "expected an index into \"geometry\", got {}", value.dump());
        const int64_t index = value.get<int64_t>();
        if (index < 0 || uint64_t(index) >= scene.geometry.size())
            fail(where, "geometry index {} is out of range (the scene has {} entries)", index, scene.geometry.size());
        // A repeat baked the entry again, into as many identical outputs (NAME-mesh-2.exr, a
        // vertex bake's NAME-i.glb), without a word.
        if (std::find(indices.begin(), indices.end(), size_t(index)) != indices.end())
            fail(where, "geometry {} is listed twice", index);
        indices.push_back(size_t(index));
    }
    return indices;
}

void registerFileSourceTypes() {
    for (const char* type : {"obj", "gltf", "glb", "ptri", "file"})
        registerSourceType(type, [type = std::string(type)](const SourceRequest& r) {
            JsonParams j(r.params, r.file, r.path);
            const std::string given = j.string("path");
            if (given.empty()) fail(j.where("path"), "must name a file, got \"\"");
            std::string path = resolveScenePath(r.baseDir, given, j.where("path"));
            // The key, for a file that is not there: with several entries (or nested scatters) a
            // bare "rock.obj: cannot open" does not say which one names it.
            std::error_code ec;
            // exists() is false for a folder that cannot be entered and a symlink loop too: those
            // say what stat() said (a CI job with wrong permissions went looking for a missing file).
            if (!std::filesystem::exists(path, ec))
                fail(j.where("path"), "{}: {}", path, ec && ec != std::errc::no_such_file_or_directory ? ec.message() : "no such file");
            const std::vector<std::string> parts = geometryParts(j);
            j.finish();
            if (type == "file" && geometryFormatOf(path) == GeometryFormat::Gltf)
                return openGeometryFile(path, GeometryFormat::Gltf, parts, r.gltfAlpha);
            if (type == "file") return openGeometryFile(path, parts);
            // The entry's type decides the reader; an extension that names another format is a
            // mistake worth stopping for, not a hint to follow.
            const GeometryFormat format = type == "obj" ? GeometryFormat::Obj
                                          : type == "ptri" ? GeometryFormat::Ptri
                                                           : GeometryFormat::Gltf;
            if (std::optional<GeometryFormat> named = geometryFormatOf(path); named && *named != format)
                fail(r.where() + ".type", "\"{}\" does not match the file {} (use the type of its format, or \"file\")",
                     type, path);
            return openGeometryFile(path, format, parts, r.gltfAlpha);
        });
}

SceneDesc parseScene(const nlohmann::json& root, const std::string& file) {
    SceneDesc scene;
    scene.file = file;
    scene.baseDir = std::filesystem::path(file).parent_path();
    // A scene named through /dev/stdin or /proc/self/fd (`bake /dev/stdin < scenes/a.json`) is
    // the file behind the link: its relative paths are that file's folder's, not /dev's.
    if (file.starts_with("/dev/") || file.starts_with("/proc/")) {
        std::error_code ec;
        if (const std::filesystem::path target = std::filesystem::canonical(file, ec); !ec && std::filesystem::is_regular_file(target, ec))
            scene.baseDir = target.parent_path();
    }
    JsonParams j(root, file, "");

    const nlohmann::json* geometry = j.raw("geometry");
    if (!geometry) j.missing("geometry");
    if (!geometry->is_array()) fail(j.where("geometry"), "expected an array of geometry entries");
    std::vector<SceneOutlineTexture> textures;
    for (size_t i = 0; i < geometry->size(); ++i) {
        JsonParams g((*geometry)[i], file, indexed("geometry", i));
        GeometryDesc desc;
        desc.path = indexed("geometry", i);
        desc.type = g.string("type");
        desc.transform = parseTransform(g);
        if (g.raw("closed")) desc.closed = g.boolean("closed", false);
        parseObjectControls(g, desc, scene);
        parseOutlineTexture(g, desc, i, scene, textures);
        desc.params = (*geometry)[i];
        for (const char* key : {"type", "transform", "closed", "cast_shadows", "receive_shadows", "receiver_offset", "max_distance",
                                "translucent", "leaf_texture", "petal_texture", "alpha_cutoff"})
            desc.params.erase(key);
        scene.geometry.push_back(std::move(desc));
    }
    initSceneAlpha(scene, addDistanceIds(scene), std::move(textures));

    const nlohmann::json* lights = j.raw("lights");
    if (!lights) j.missing("lights");
    if (!lights->is_array() || lights->empty()) fail(j.where("lights"), "expected a non-empty array of lights");
    uint64_t samples = 0, sets = 1;
    for (size_t i = 0; i < lights->size(); ++i) {
        scene.lights.push_back(parseLight(JsonParams((*lights)[i], file, indexed("lights", i))));
        // Every receiver holds a bit per sample of all lights, and every set a position per sample.
        samples = checkedSum(samples, uint64_t(scene.lights.back().samples), kMaxSceneSamples, j.where("lights"),
                             "light samples in all");
        sets = std::max(sets, uint64_t(scene.lights.back().sampleSets));
    }
    checkedProduct({samples, sets}, kMaxSamplePositions, j.where("lights"), "sample positions (samples x sets)");

    const nlohmann::json* receivers = j.raw("receivers");
    if (!receivers) j.missing("receivers");
    scene.receivers = *receivers;

    // Resolved now, checked against the scene's directory only by a bake that writes it (-o
    // replaces it): checkSceneOutput().
    // Without "output" the kind's own format: out/shadows.exr, .vdb for a volume, .npy for points.
    const std::string fallback = std::filesystem::path(scene.output).replace_extension(receiverKindExtension(scene.receivers)).string();
    scene.output = (scene.baseDir / j.string("output", fallback)).lexically_normal().string();
    if (const nlohmann::json* bake = j.raw("bake")) {
        scene.bakeOptions = *bake;
        parseOptions(JsonParams(*bake, file, "bake"), scene);
    }
    if (const nlohmann::json* exr = j.raw("exr")) scene.exr = parseExrSettings(JsonParams(*exr, file, "exr"));
    j.finish();
    validateReceiverKind(scene.receivers, scene);  // errors now; the bake makes the kind
    return scene;
}

void checkSceneOutput(const SceneDesc& scene) {
    if (!scene.outputFromScene) return;
    resolveScenePath(scene.baseDir, std::filesystem::absolute(scene.output).string(), scene.file + ": output");
}

SceneDesc loadScene(const std::string& path) { return parseScene(readJsonFile(path), path); }

namespace {

TriangleSourcePtr openGeometry(const SceneDesc& scene, bool exporting) {
    std::vector<TriangleSourcePtr> parts;
    for (size_t i = 0; i < scene.geometry.size(); ++i) {
        const GeometryDesc& g = scene.geometry[i];
        // An export keeps no alpha ids: they mean something only with this scene's table.
        std::shared_ptr<const GltfAlphaIds> alpha = exporting ? nullptr : sceneAlphaIds(scene, i);
        TriangleSourcePtr source = openSource(g.type, SourceRequest{g.params, scene.file, g.path, scene.baseDir, alpha});
        if (!g.transform.isIdentity())
            source = std::make_unique<TransformedSource>(std::move(source), g.transform.matrix(),
                                                         fmt::format("{}: geometry[{}].transform", scene.file, i));
        source = std::make_unique<FiniteSource>(std::move(source), fmt::format("{}: geometry[{}] ({})", scene.file, i, g.type));
        if (g.closed)
            source = std::make_unique<FlagSource>(std::move(source), *g.closed ? kTriangleClosed : 0u,
                                                  *g.closed ? 0u : kTriangleClosed | kTriangleSolidStart);
        source = withObjectControls(std::move(source), g, scene.file, exporting, alpha != nullptr);
        // An export keeps the built-in outline, which means the same in every scene.
        if (const SceneOutlineTexture* t = exporting ? nullptr : sceneOutlineTexture(scene, i))
            source = std::make_unique<BuiltinIdSource>(std::move(source), t->ids, t->key, false);
        parts.push_back(std::move(source));
    }
    return std::make_unique<ConcatSource>(std::move(parts));
}

}  // namespace

TriangleSourcePtr openSceneGeometry(const SceneDesc& scene) { return openGeometry(scene, false); }

TriangleSourcePtr openSceneGeometryForExport(const SceneDesc& scene) { return openGeometry(scene, true); }

}  // namespace penumbra
