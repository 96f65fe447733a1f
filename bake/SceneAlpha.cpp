#include "bake/SceneAlpha.h"

#include "bake/kinds/ReceiverKind.h"
#include "stream/GeometryFile.h"
#include "stream/util/Error.h"
#include "bake/MemoryPlan.h"
#include "stream/util/Memory.h"

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

void plan(const SceneDesc& scene, GltfAlphaState& state) {
    if (state.planned) return;
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

void initSceneAlpha(SceneDesc& scene, std::shared_ptr<AlphaTable> table) {
    const bool gltf = std::any_of(scene.geometry.begin(), scene.geometry.end(), [](const GeometryDesc& g) {
        return g.type == "gltf" || g.type == "glb" || g.type == "file";
    });
    if (gltf && !table) table = std::make_shared<AlphaTable>();
    if (table) scene.options.alphaTable = table;
    if (!gltf) return;
    scene.gltfAlpha = std::make_shared<GltfAlphaState>();
    scene.gltfAlpha->table = std::move(table);
}

const GltfAlphaState* planSceneAlpha(const SceneDesc& scene) {
    if (!scene.gltfAlpha) return nullptr;
    std::lock_guard lock(scene.gltfAlpha->mutex);
    plan(scene, *scene.gltfAlpha);
    return scene.gltfAlpha.get();
}

void checkSceneAlphaBudget(const SceneDesc& scene, uint64_t budgetBytes, const std::string& label) {
    const GltfAlphaState* state = planSceneAlpha(scene);
    if (!state || budgetBytes == 0) return;
    for (const SceneAlphaEntry& e : state->entries)
        for (const GltfAlphaImage& image : e.plan.images)
            if (kBaselineBytes + image.decodeBytes + image.bitBytes > budgetBytes)
                fail(image.where, "a {} x {} texture needs {} to decode, more than {} {} allows", image.width, image.height,
                     formatBytes(image.decodeBytes + image.bitBytes), label, formatBytes(budgetBytes));
}

std::shared_ptr<const GltfAlphaIds> sceneAlphaIds(const SceneDesc& scene, size_t geometry) {
    if (!scene.gltfAlpha) return nullptr;
    GltfAlphaState& state = *scene.gltfAlpha;
    std::lock_guard lock(state.mutex);
    plan(scene, state);
    if (!state.built) {
        for (SceneAlphaEntry& e : state.entries)
            e.ids = buildGltfAlpha(loadGltfDocument(e.path), *state.table, scene.geometry[e.geometry].maxDistance.value_or(INFINITY));
        state.built = true;
    }
    for (const SceneAlphaEntry& e : state.entries)
        if (e.geometry == geometry) return e.ids;
    return nullptr;
}

}  // namespace penumbra
