#pragma once
/// @file Scene.h
/// @brief The scene file (JSON): geometry, lights, receivers, output and bake options.
/// docs/scene-format.md is the reference for every key.

#include "bake/cast/CastOptions.h"
#include "bake/output/ExrSettings.h"
#include "bake/light/Light.h"
#include "stream/util/JsonParams.h"
#include "stream/Transform.h"
#include "receivers/ReceiverSet.h"
#include "stream/AlphaTable.h"
#include "stream/TriangleSource.h"

#include <nlohmann/json.hpp>

#include <array>
#include <optional>

#include <filesystem>
#include <string>
#include <vector>

namespace penumbra {

struct GltfAlphaState;  // bake/SceneAlpha.h

/// Largest bake.epsilon: the receiver-end margin is epsilon * max(1, |r|), and a tenth of the
/// scene's scale already removes almost every shadow.
inline constexpr double kMaxEpsilon = 0.1;
/// Most light samples of all lights together: every receiver keeps a bit per sample.
inline constexpr uint64_t kMaxSceneSamples = uint64_t(1) << 20;
/// Most sample positions (samples of all lights x the largest number of sets), 768 MiB of them.
inline constexpr uint64_t kMaxSamplePositions = uint64_t(1) << 26;

/// @brief One "geometry" entry: a file or a generator, with its placement.
struct GeometryDesc {
    std::string type;
    nlohmann::json params;  ///< the entry without "type" and "transform"
    Transform transform;
    std::string path;       ///< key path for messages, "geometry[1]"
    /// "closed": true marks every triangle as part of a closed, outward-wound surface
    /// (kTriangleClosed), false clears the mark that a generator set; absent keeps the source's.
    std::optional<bool> closed;
    /// "cast_shadows": false: the triangles are seen by the receivers' passes but block nothing
    /// (kTriangleNoCast).
    bool castShadows = true;
    /// "receive_shadows": false: receivers made on this entry's surface are unshadowed (V = 1).
    bool receiveShadows = true;
    /// "receiver_offset": receivers made on this entry's surface move this far along their
    /// normal (scene units) before casting.
    double receiverOffset = 0.0;
    /// "max_distance": a hit on this entry's triangles blocks only within this distance of the
    /// receiver (AlphaRule.h, distanceAtHit).
    std::optional<double> maxDistance;
    /// The receiver class of the entry's triangles (Triangle.h; SceneDesc::receiverClasses).
    uint32_t receiverClass = 0;
    /// With maxDistance: the alpha id its triangles take for alpha id a < kBuiltinAlphaCount.
    std::array<uint32_t, kBuiltinAlphaCount> distanceIds{};
    /// "translucent": {"color", "opacity"}: the translucent id (stream/Translucency.h) every
    /// triangle of the entry takes; they attenuate instead of blocking.
    std::optional<uint32_t> translucentId;
};


/// @brief A parsed scene. Paths are already resolved relative to the scene file.
struct SceneDesc {
    std::string file;  ///< the scene file, for messages
    std::filesystem::path baseDir;
    std::vector<GeometryDesc> geometry;
    /// Index = receiver class (Triangle.h, receiverClassOf()); class 0 is the default pair.
    std::vector<ReceiverClass> receiverClasses{ReceiverClass{}};
    std::vector<LightDesc> lights;
    nlohmann::json receivers;  ///< the "receivers" object; ReceiverKind.h makes the kind from it
    std::string output = "out/shadows.exr";
    /// True while `output` is the scene's own (not -o), which must stay in the scene's directory.
    bool outputFromScene = true;
    ExrSettings exr;  ///< "exr": pixel type, tiles and what R, G, B hold (camera and lightmap EXRs)
    CastOptions options;
    /// The scene's "bake" object as written, for the keys a method reads itself (Caster.h).
    nlohmann::json bakeOptions = nlohmann::json::object();
    uint64_t seed = 1;
    /// bake.smooth_shading: smooth coherent shading in the camera's PNG preview (the EXR keeps the
    /// plain irradiance). On by default: it costs 8 bytes per pixel during the scan (the visible
    /// triangle's stream position) and a vertex table found again in the bucket pass.
    bool smoothShading = true;
    /// The glTF entries' alpha-tested (MASK) materials, planned and built into options.alphaTable
    /// on demand (SceneAlpha.h); shared by copies of the scene. Null without glTF entries.
    std::shared_ptr<GltfAlphaState> gltfAlpha;
};

/// @brief Reads and validates a scene file.
/// @throw InputError naming the file and the key ("scene.json: lights[0].u: expected an array of 3
/// numbers", "scene.json: receivers.colour: unknown key").
SceneDesc loadScene(const std::string& path);
/// @brief Same, from JSON text already in memory; @p file is used in messages and for paths.
SceneDesc parseScene(const nlohmann::json& root, const std::string& file);

/// @brief Refuses a scene-named output outside the scene's directory (SafePath.h), unless -o
/// replaced it (outputFromScene false) or `--allow-outside-uris` was given.
/// @throw InputError "scene.json: output: "../x.exr" leaves the scene's directory ...".
void checkSceneOutput(const SceneDesc& scene);

/// @brief Opens every geometry entry as one stream, in scene order, with transforms applied.
TriangleSourcePtr openSceneGeometry(const SceneDesc& scene);
/// @brief The same triangles for a file other scenes read (`penumbra generate`): they keep the
/// "cast_shadows" mark, not the receiver classes or "max_distance" ids, which only this scene's
/// receiverClasses and alpha table give a meaning.
TriangleSourcePtr openSceneGeometryForExport(const SceneDesc& scene);

/// @brief The "parts" of a geometry entry: the OBJ o/g groups it takes (empty: the whole file).
/// @throw InputError naming the key when it is not a non-empty array of strings.
std::vector<std::string> geometryParts(const JsonParams& entry);

/// @brief The indices into the scene's "geometry" list that key @p key of @p j holds (a kind's
/// "meshes", a band's "geometry"): a non-empty array of in-range integers, each listed once.
/// @throw InputError naming the key, or KEY[i] for a bad element.
std::vector<size_t> geometryIndices(const JsonParams& j, const std::string& key, const SceneDesc& scene);

/// @brief Registers the file-backed geometry types: obj, gltf, glb, ptri and "file" (by extension).
void registerFileSourceTypes();

}  // namespace penumbra
