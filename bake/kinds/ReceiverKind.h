#pragma once
/// @file ReceiverKind.h
/// @brief The extension point for receiver types (camera, points, lightmap, vertices, volume):
/// where a bake's receivers come from and what it writes for them.
///
/// A kind is made from the scene's "receivers" object by a registered factory. The pipeline then
/// (1) feeds it every chunk of the scene stream during the scan pass (camera receivers rasterize
/// there; kinds that do not need the stream ignore it), (2) asks it for the receivers, (3) casts
/// them, (4) lets it refine: ask for more receivers after seeing the first results (camera
/// antialiasing), casting only those, and (5) hands it the per-receiver results to write.

#include "bake/light/Light.h"
#include "bake/shading/ReceiverShading.h"
#include "receivers/ReceiverSet.h"
#include "stream/util/JsonParams.h"
#include "stream/Triangle.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

struct SceneDesc;
struct ReceiverPolygons;  // receivers/LightmapReceivers.h

/// @brief What a kind's writer gets.
struct OutputContext {
    const SceneDesc& scene;
    const ReceiverSet& receivers;
    const LightSamples& samples;
    const ReceiverResults& results;
    std::string output;  ///< the output path (scene "output" or -o)
    /// Receivers [0, firstPass) are the first pass's; later ones are refinement() receivers.
    size_t firstPass = receivers.size();
};

class ReceiverKind {
public:
    virtual ~ReceiverKind() = default;
    /// Bytes held during the scan pass (a z-buffer, say, and the receiver set being made), for the
    /// memory plan.
    virtual uint64_t scanBytes() const { return 0; }
    /// Bytes held while writing outputs for @p receivers receivers, for the memory plan.
    virtual uint64_t outputBytes(uint64_t receivers) const { return 0; }
    /// At most this many receivers, known before the scan pass (a camera's pixels, a lightmap's
    /// texels, a box's voxels, a point file's rows), so that the plan refuses a request that
    /// cannot fit before making a single receiver; nullopt when only the scan can tell.
    virtual std::optional<uint64_t> receiverBound() const { return std::nullopt; }
    /// @brief The most residentBytes() can reach with @p receivers receivers over @p triangles
    /// triangles (unknown: nullopt), for plans made before the rescan. After receivers() it may
    /// use what the scan found.
    virtual uint64_t maxResidentBytes(uint64_t receivers, std::optional<uint64_t> triangles) const { return 0; }
    /// Every chunk of the scene stream, in stream order, during the scan pass.
    virtual void scan(std::span<const Triangle> chunk) {}
    /// The receivers, after the scan pass. Called once.
    virtual ReceiverSet receivers() = 0;
    /// True when the kind needs one more pass over the scene stream after receivers() (camera
    /// smooth shading gathers the faces around its visible vertices); the pipeline then calls
    /// rescan() with every chunk, in stream order, before casting.
    virtual bool wantsRescan() const { return false; }
    virtual void rescan(std::span<const Triangle> chunk) {}
    /// Bytes the kind holds from after the rescan until its outputs are written (smooth shading's
    /// vertex table), for the memory plan. Asked after the rescan.
    virtual uint64_t residentBytes() const { return 0; }
    /// True when the kind wants every blocker once per cast pass; the pipeline then calls
    /// castChunk() with each chunk the first memory tile casts (replay order, not stream order).
    virtual bool wantsCastChunks() const { return false; }
    virtual void castChunk(std::span<const Triangle> chunk) {}

    /// Adaptive refinement in a second pass (camera antialiasing): after the first cast, refine()
    /// sees the receivers and their results and returns true when it wants more receivers. The
    /// pipeline then feeds every blocker (replay order) to refineScan(), appends the receivers
    /// refinedReceivers() returns (once) to the set and casts only those, with the same light
    /// samples and method; write() then gets both passes (OutputContext::firstPass).
    virtual bool refine(const ReceiverSet& receivers, const ReceiverResults& results) { return false; }
    /// True when refine() may add receivers (which can lie outside the first pass's receivers, so
    /// the bucket pass must not cull blockers by the first pass's reach).
    virtual bool mayRefine() const { return false; }
    virtual void refineScan(std::span<const Triangle> chunk) {}
    virtual ReceiverSet refinedReceivers() { return {}; }
    /// Bytes held during refineScan(), for the memory plan (asked after refine()).
    virtual uint64_t refineBytes() const { return 0; }
    /// The receivers' polygons and texels, for kinds whose receivers are texels of receiver
    /// polygons (lightmaps); null for the others. Filled by receivers(), so it is complete after it;
    /// the pointer itself may be asked for before, to see whether the kind has polygons.
    virtual const ReceiverPolygons* receiverPolygons() const { return nullptr; }
    /// Kind-specific entries for the stats JSON (null for none), asked after write().
    virtual nlohmann::json stats() const { return nullptr; }
    /// Writes the outputs. Every file goes through AtomicFile (no partial outputs).
    virtual void write(const OutputContext& context) = 0;
};

/// @brief Everything a factory gets: the "receivers" object (strict: finish() is called by the
/// registry after the factory returns) and the scene (its folder, geometry list, lights).
using ReceiverKindFactory = std::function<std::unique_ptr<ReceiverKind>(const JsonParams& params, const SceneDesc& scene)>;

/// @brief Registers (or replaces) receiver type @p type.
void registerReceiverKind(const std::string& type, ReceiverKindFactory factory);

/// @brief Makes the kind named by the object's "type" key.
/// @throw InputError naming the key for an unknown type or bad parameters.
std::unique_ptr<ReceiverKind> makeReceiverKind(const nlohmann::json& receivers, const SceneDesc& scene);

/// @brief Registers a receiver type from the kind's own file, as a namespace-scope constant
/// (`const ReceiverKindRegistration kCamera{"camera", &makeCameraKind};`), so that no central
/// file lists the kinds. The library is linked whole (CMakeLists.txt) so that none is dropped.
struct ReceiverKindRegistration {
    ReceiverKindRegistration(const std::string& type, ReceiverKindFactory factory) {
        registerReceiverKind(type, std::move(factory));
    }
};

/// @brief Refuses an output whose extension (any case) is not @p extension: the extension names
/// the format, and a kind writes only its own (`-o x.tiff` or `-o x.png` of a camera bake).
/// @throw InputError naming the output ("--output" when -o gave it) and the format the kind writes.
void requireOutputExtension(const SceneDesc& scene, const std::string& extension, const std::string& kind);

/// @brief A path from a scene file resolved against the scene's folder, which it must not leave
/// (SafePath.h; `--allow-outside-uris` lifts the rule). @p where names the key in messages.
/// @throw InputError naming @p where (or the path) when the path leaves the folder.
std::string resolveScenePath(const std::filesystem::path& baseDir, const std::string& path, const std::string& where = "");

}  // namespace penumbra
