#include "bake/SceneAlpha.h"

#include "bake/kinds/ReceiverKind.h"
#include "stream/AlphaImage.h"
#include "stream/GeometryFile.h"
#include "stream/GltfConvert.h"
#include "stream/GltfDocument.h"
#include "stream/util/Error.h"
#include "bake/MemoryPlan.h"
#include "stream/util/Memory.h"

#include <fmt/ranges.h>

#include <cmath>
#include <filesystem>
#include <optional>

namespace penumbra {
namespace {

/// The glTF file entry @p g reads, or empty for another type.
std::string gltfPathOf(const SceneDesc& scene, const GeometryDesc& g) {
    if (g.type != "gltf" && g.type != "glb" && g.type != "file") return {};
    auto it = g.params.find("path");
    if (it == g.params.end() || !it->is_string()) return {};
    const std::string path = resolveScenePath(scene.baseDir, it->get<std::string>(), scene.file + ": " + g.path + ".path");
    // Another format's file is left to the entry's reader, which says what is wrong with it.
    const std::optional<GeometryFormat> format = geometryFormatOf(path);
    if (g.type == "file" ? format != GeometryFormat::Gltf : format && format != GeometryFormat::Gltf) return {};
    return path;
}

/// A generator's texture: its header, counted as a glTF texture is (its map and two entries held,
/// its decode while building).
void planOutlineTexture(SceneOutlineTexture& t, GltfAlphaState& state) {
    t.plan.where = t.key + ": " + t.path;
    const AlphaImageHeader h = readAlphaImageHeader(readAlphaImageFile(t.path, t.key), "", t.plan.where);
    t.plan.width = uint32_t(h.width), t.plan.height = uint32_t(h.height);
    t.plan.decodeBytes = h.decodeBytes(), t.plan.bitBytes = h.bitBytes();
    state.tableBytes += t.plan.bitBytes + sizeof(AlphaMap) + 2 * sizeof(AlphaEntry);
    state.buildBytes = std::max(state.buildBytes, t.plan.decodeBytes + t.plan.bitBytes);
}

/// Decodes a generator's texture into @p table: a clamped map, and the canonical quad layout's
/// lower (0,0) (1,0) (1,1) and upper (0,0) (1,1) (0,1) entries in place of the outline's.
void buildOutlineTexture(SceneOutlineTexture& t, AlphaTable& table) {
    const std::vector<uint8_t> data = readAlphaImageFile(t.path, t.key);
    AlphaMap map = decodeAlphaImage(data, readAlphaImageHeader(data, "", t.plan.where), 1.0, t.cutoff, t.plan.where);
    map.wrapS = map.wrapT = AlphaWrap::Clamp;
    map.name = t.plan.where;
    const uint32_t index = table.addMap(std::move(map));
    const glm::dvec2 c00(0, 0), c10(1, 0), c11(1, 1), c01(0, 1);
    const uint32_t lower = table.addEntry({index, {c00, c10, c11}}), upper = table.addEntry({index, {c00, c11, c01}});
    for (uint32_t a = 0; a < kBuiltinAlphaCount; ++a) t.ids[a] = a;
    t.ids[t.petal ? kAlphaPetalLower : kAlphaLeafLower] = lower;
    t.ids[t.petal ? kAlphaPetalUpper : kAlphaLeafUpper] = upper;
}

void plan(const SceneDesc& scene, GltfAlphaState& state) {
    if (state.planned) return;
    for (SceneOutlineTexture& t : state.textures) planOutlineTexture(t, state);
    for (size_t i = 0; i < scene.geometry.size(); ++i) {
        const std::string path = gltfPathOf(scene, scene.geometry[i]);
        std::error_code ec;
        if (path.empty() || !std::filesystem::is_regular_file(path, ec)) continue;  // the reader says what is wrong
        SceneAlphaEntry e{i, path, planGltfAlpha(loadGltfDocument(path)), nullptr};
        if (e.plan.empty()) continue;
        state.tableBytes += e.plan.tableBytes;
        state.buildBytes = std::max(state.buildBytes, e.plan.buildBytes);
        state.entries.push_back(std::move(e));
    }
    state.planned = true;
}

}  // namespace

void initSceneAlpha(SceneDesc& scene, std::shared_ptr<AlphaTable> table, std::vector<SceneOutlineTexture> textures) {
    const bool gltf = !textures.empty() || std::any_of(scene.geometry.begin(), scene.geometry.end(), [](const GeometryDesc& g) {
        return g.type == "gltf" || g.type == "glb" || g.type == "file";
    });
    if (gltf && !table) table = std::make_shared<AlphaTable>();
    if (table) scene.options.alphaTable = table;
    if (!gltf) return;
    scene.gltfAlpha = std::make_shared<GltfAlphaState>();
    scene.gltfAlpha->table = std::move(table);
    scene.gltfAlpha->textures = std::move(textures);
}

const GltfAlphaState* planSceneAlpha(const SceneDesc& scene) {
    if (!scene.gltfAlpha) return nullptr;
    std::lock_guard lock(scene.gltfAlpha->mutex);
    plan(scene, *scene.gltfAlpha);
    return scene.gltfAlpha.get();
}

void checkSceneAlphaBudget(const SceneDesc& scene, uint64_t budgetBytes, const std::string& label, uint64_t overhead,
                           uint64_t namedSlack, uint64_t leastOtherwise) {
    const GltfAlphaState* state = planSceneAlpha(scene);
    if (!state || budgetBytes == 0) return;
    auto check = [&](const GltfAlphaImage& image) {
        // The limit named is the one given (an address-space limit, not what is left of it), and
        // the least counts the bake's baseline: "needs 130 KiB, more than 18.7 MiB allows" was
        // said of a 100 MiB limit.
        const uint64_t needed = kBaselineBytes + image.decodeBytes + image.bitBytes;
        if (needed > budgetBytes)
            fail(image.where, "a {} x {} texture needs {} to decode; with the bake's baseline ({}), {} {} is too small: at least {} is needed",
                 image.width, image.height, formatBytes(image.decodeBytes + image.bitBytes), formatBytes(kBaselineBytes), label,
                 refusedBudgetText(budgetBytes + overhead), budgetText(std::max(needed + overhead + namedSlack, leastOtherwise)));
    };
    for (const SceneAlphaEntry& e : state->entries)
        for (const GltfAlphaImage& image : e.plan.images) check(image);
    for (const SceneOutlineTexture& t : state->textures) check(t.plan);
}

namespace {

/// The built state (plan, then build, once). Call with the state's mutex held.
GltfAlphaState& built(const SceneDesc& scene) {
    GltfAlphaState& state = *scene.gltfAlpha;
    plan(scene, state);
    if (!state.built) {
        for (SceneAlphaEntry& e : state.entries)
            e.ids = buildGltfAlpha(loadGltfDocument(e.path), *state.table, scene.geometry[e.geometry].maxDistance.value_or(INFINITY));
        for (SceneOutlineTexture& t : state.textures) buildOutlineTexture(t, *state.table);
        state.built = true;
    }
    return state;
}

}  // namespace

std::shared_ptr<const GltfAlphaIds> sceneAlphaIds(const SceneDesc& scene, size_t geometry) {
    if (!scene.gltfAlpha) return nullptr;
    std::lock_guard lock(scene.gltfAlpha->mutex);
    for (const SceneAlphaEntry& e : built(scene).entries)
        if (e.geometry == geometry) return e.ids;
    return nullptr;
}

const SceneOutlineTexture* sceneOutlineTexture(const SceneDesc& scene, size_t geometry) {
    if (!scene.gltfAlpha) return nullptr;
    GltfAlphaState& state = *scene.gltfAlpha;
    // The list is fixed when the scene is parsed; only the ids wait for the build.
    auto it = std::find_if(state.textures.begin(), state.textures.end(), [&](const SceneOutlineTexture& t) { return t.geometry == geometry; });
    if (it == state.textures.end()) return nullptr;
    std::lock_guard lock(state.mutex);
    built(scene);
    return &*it;
}

void warnExportDrops(const SceneDesc& scene) {
    for (size_t i = 0; i < scene.geometry.size(); ++i) {
        const GeometryDesc& g = scene.geometry[i];
        if (const std::string path = gltfPathOf(scene, g); !path.empty()) warnIfMaterialsDropped(path, loadGltfDocument(path), "generate");
        std::vector<std::string> keys;
        if (g.translucentId) keys.push_back("\"translucent\"");
        if (g.maxDistance) keys.push_back("\"max_distance\"");
        bool texture = false;
        if (scene.gltfAlpha)
            for (const SceneOutlineTexture& t : scene.gltfAlpha->textures) texture |= t.geometry == i;
        if (texture) keys.push_back("its leaf or petal texture");
        if (keys.empty()) continue;
        printWarning("{}: {}: {} not written: generate writes triangles only, so these block as plain opaque ones{}; bake the scene "
                     "to keep {}",
                     scene.file, g.path, fmt::format("{}", fmt::join(keys, ", ")), texture ? " (cut-outs with the built-in outline)" : "",
                     keys.size() > 1 ? "them" : "it");
    }
}

}  // namespace penumbra
