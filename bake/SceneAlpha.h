#pragma once
/// @file SceneAlpha.h
/// @brief A scene's alpha-tested glTF blockers (stream/GltfAlpha.h) and generators' leaf and
/// petal textures ("leaf_texture", "petal_texture"): planned from the images' headers when the
/// bake checks its memory, then built once, in scene order (glTF files, then generator
/// textures), into the scene's alpha table before the first pass reads the geometry. The table is complete and read-only
/// before any method casts, and the same scene gives the same ids in every process (shards,
/// resume, rescans), because the build reads the same files in the same order.

#include "bake/Scene.h"
#include "stream/GltfAlpha.h"

#include <array>
#include <memory>
#include <mutex>
#include <vector>

namespace penumbra {

/// One glTF geometry entry with MASK materials.
struct SceneAlphaEntry {
    size_t geometry = 0;  ///< index into SceneDesc::geometry
    std::string path;     ///< the resolved file
    GltfAlphaPlan plan;
    std::shared_ptr<const GltfAlphaIds> ids;  ///< after the build
};

/// One generator entry's leaf or petal texture: a 1-bit map on the canonical quad layout, whose
/// two entries replace the built-in outline's lower and upper ids.
struct SceneOutlineTexture {
    size_t geometry = 0;  ///< index into SceneDesc::geometry
    std::string path;     ///< the image, resolved against the scene's directory
    std::string key;      ///< "FILE: geometry[i].leaf_texture", for messages
    double cutoff = 0.5;  ///< "alpha_cutoff"
    bool petal = false;   ///< replaces the petal outline ("petal_texture"), else the leaf's
    GltfAlphaImage plan;  ///< after planning; where = "KEY: PATH"
    std::array<uint32_t, kBuiltinAlphaCount> ids{};  ///< after the build: built-in id -> the entry's
};

/// @brief The state SceneDesc::gltfAlpha shares between copies of a scene.
struct GltfAlphaState {
    std::mutex mutex;
    bool planned = false, built = false;
    std::shared_ptr<AlphaTable> table;  ///< the scene's table (SceneDesc::options.alphaTable)
    std::vector<SceneAlphaEntry> entries;
    std::vector<SceneOutlineTexture> textures;
    uint64_t tableBytes = 0, buildBytes = 0;  ///< sums of the entries' plans
};

/// @brief Gives @p scene its alpha state when an entry may be a glTF file or has an outline
/// texture (@p textures, parsed from the entries), using @p table (the max_distance table, or
/// null: a new one) as the scene's alpha table.
void initSceneAlpha(SceneDesc& scene, std::shared_ptr<AlphaTable> table, std::vector<SceneOutlineTexture> textures);

/// @brief Step 1 (once per scene): loads the glTF entries' documents and image headers.
/// @throw InputError as planGltfAlpha().
const GltfAlphaState* planSceneAlpha(const SceneDesc& scene);

/// @brief Refuses, before any work, an image that does not fit in @p budgetBytes (0: unlimited)
/// with the bake's baseline when it is decoded.
/// @param overhead, @p namedSlack as BakeBudget's: the limit the message names is the budget plus
///        @p overhead, and the least it asks for adds @p namedSlack.
/// @param leastOtherwise the least budget or limit the checks after this one would name (the
///        plan before the scan without the sources), named instead when it is larger: naming the
///        texture's need alone sent a user to a budget the next check refused again (49M, then 115M).
/// @throw InputError "FILE: material M ("name"): image I: ...", naming the least budget or limit.
void checkSceneAlphaBudget(const SceneDesc& scene, uint64_t budgetBytes, const std::string& label, uint64_t overhead = 0,
                           uint64_t namedSlack = 0, uint64_t leastOtherwise = 0);

/// @brief Step 2 (once per scene): decodes the textures and gives the triangles their ids.
/// @return for generator entry @p geometry with an outline texture, its built texture (ids: the
/// id each built-in alpha id of its triangles becomes), or null when it has none.
/// @throw InputError "FILE: geometry[i].leaf_texture: ..." for a missing or undecodable image.
const SceneOutlineTexture* sceneOutlineTexture(const SceneDesc& scene, size_t geometry);

/// @brief Warns, per entry of @p scene, about what `generate` cannot write to a geometry file:
/// a glTF's cut-out and blended materials (with their count), and the entry's "translucent",
/// "max_distance" and "leaf_texture"/"petal_texture" keys. Such triangles block as opaque
/// ones (or with the built-in outline) when the file is baked.
void warnExportDrops(const SceneDesc& scene);

/// @brief Step 2 (once per scene): decodes the textures and gives the triangles their ids.
/// @return the ids of geometry entry @p geometry, or null when it has none.
std::shared_ptr<const GltfAlphaIds> sceneAlphaIds(const SceneDesc& scene, size_t geometry);

}  // namespace penumbra
