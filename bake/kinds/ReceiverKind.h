#pragma once
/// @file ReceiverKind.h
/// @brief The extension point for receiver types (camera, points, lightmap, vertices, volume):
/// where a bake's receivers come from and what it writes for them.
///
/// A kind is made once per bake from the scene's "receivers" object by a registered factory. The
/// pipeline then (1) hands it the chunks of the passes over the stream it wants (StreamPass: the
/// scan, where camera receivers rasterize), (2) asks it for the receivers, (3) casts them, (4)
/// lets it refine: ask for more receivers after seeing the first results (camera antialiasing),
/// casting only those, and (5) hands it the per-receiver results to write.

#include "bake/light/Light.h"
#include "bake/shading/ReceiverShading.h"
#include "receivers/ReceiverSet.h"
#include "stream/util/JsonParams.h"
#include "stream/util/Progress.h"
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
    /// The write phase's progress, in ReceiverKind::outputWork() units; null: none shown.
    ProgressReporter* progress = nullptr;
};

/// @brief The walks over the blocker stream a kind can ride along with, in bake order. The
/// pipeline owns every read of the source (at most two: the scan and the bucket pass) and hands
/// each pass's chunks to the kinds that want them (ReceiverKind::wantsPass).
enum class StreamPass : uint8_t {
    Scan,    ///< stream order, before receivers(): a camera rasterizes, a volume marks its band
    Rescan,  ///< stream order, after receivers() and before casting (rides the bucket pass)
    Cast,    ///< replay order: the chunks the first memory tile casts
    Refine,  ///< replay order, after refine() returned true: the refinement's receivers
};

/// The geometry entry of a chunk whose triangles come from more than one (replay order).
inline constexpr uint32_t kAnyGeometryEntry = UINT32_MAX;

/// @brief One chunk of a pass: the triangles, and the scene "geometry" entry (its index) they
/// all came from, or kAnyGeometryEntry in replay order (the buckets mix entries).
struct StreamChunk {
    std::span<const Triangle> triangles;
    uint32_t entry = kAnyGeometryEntry;
};

class ReceiverKind {
public:
    virtual ~ReceiverKind() = default;

    /// @name Memory, for the plan (MemoryPlan.h)
    /// @{
    /// Bytes held while writing outputs for @p receivers receivers.
    virtual uint64_t outputBytes(uint64_t receivers) const { return 0; }
    /// At most this many receivers, known before the scan pass (a camera's pixels, a lightmap's
    /// texels, a box's voxels, a point file's rows), so that the plan refuses a request that
    /// cannot fit before making a single receiver; nullopt when only the scan can tell.
    virtual std::optional<uint64_t> receiverBound() const { return std::nullopt; }
    /// @brief The most residentBytes() can reach with @p receivers receivers over @p triangles
    /// triangles (unknown: nullopt), for plans made before the rescan. After receivers() it may
    /// use what the scan found.
    virtual uint64_t maxResidentBytes(uint64_t receivers, std::optional<uint64_t> triangles) const { return 0; }
    /// Bytes the kind holds from after the rescan until its outputs are written (smooth shading's
    /// vertex table). Asked after the rescan.
    virtual uint64_t residentBytes() const { return 0; }
    /// @}

    /// @name Passes over the stream
    /// @{
    /// True when the kind takes part in @p pass. Scan, Rescan and Cast are asked before the scan
    /// pass; Refine only after refine() returned true.
    virtual bool wantsPass(StreamPass pass) const { return false; }
    /// Every chunk of @p pass, in the pass's order, when wantsPass(pass).
    virtual void consume(StreamPass pass, const StreamChunk& chunk) {}
    /// Bytes held during @p pass on top of residentBytes() (a z-buffer and the receiver set made
    /// from it during the scan; the refinement's rasterizer, asked after refine()).
    virtual uint64_t passBytes(StreamPass pass) const { return 0; }
    /// @}

    /// The receivers, after the scan pass. Called once.
    virtual ReceiverSet receivers() = 0;
    /// @brief Whether long work of the kind's own in receivers() (a lightmap atlas's packing)
    /// shows progress on stderr: the bake sets it from --quiet; a kind made elsewhere is quiet.
    void setQuiet(bool quiet) { quiet_ = quiet; }
    bool quiet() const { return quiet_; }

    /// Adaptive refinement in a second pass (camera antialiasing): after the first cast, refine()
    /// sees the receivers and their results and returns true when it wants more receivers. The
    /// pipeline then runs the Refine pass over every blocker, appends the receivers
    /// refinedReceivers() returns (once) to the set and casts only those, with the same light
    /// samples and method; write() then gets both passes (OutputContext::firstPass).
    virtual bool refine(const ReceiverSet& receivers, const ReceiverResults& results) { return false; }
    /// True when refine() may add receivers (which can lie outside the first pass's receivers, so
    /// the bucket pass must not cull blockers by the first pass's reach).
    virtual bool mayRefine() const { return false; }
    virtual ReceiverSet refinedReceivers() { return {}; }
    /// The most receivers refinedReceivers() can return, asked after refine() returned true, so
    /// that the plan checks the refinement's cast and outputs before its pass.
    virtual uint64_t maxRefinedReceivers() const { return 0; }

    /// The receivers' polygons and texels, for kinds whose receivers are texels of receiver
    /// polygons (lightmaps); null for the others. Filled by receivers(), so it is complete after it;
    /// the pointer itself may be asked for before, to see whether the kind has polygons.
    virtual const ReceiverPolygons* receiverPolygons() const { return nullptr; }
    /// Kind-specific entries for the stats JSON (null for none), asked after write().
    virtual nlohmann::json stats() const { return nullptr; }
    /// The files write() will make for the bake's @p output that only the scan names (a
    /// lightmap's per-mesh maps), asked after receivers(), so that they are checked against the
    /// bake's other outputs before the cast; empty for kinds whose files the output names alone
    /// (receiverKindDerivedOutputs()).
    virtual std::vector<std::string> outputFiles(const std::string& output) const { return {}; }
    /// Writes the outputs. Every file goes through AtomicFile (no partial outputs).
    virtual void write(const OutputContext& context) = 0;
    /// Units of work write() reports to OutputContext::progress (a camera: its rows); 0 when it
    /// reports none, and the phase shows its elapsed time only.
    virtual uint64_t outputWork() const { return 0; }

private:
    bool quiet_ = true;
};

/// @brief What a factory is asked for: the kind a bake runs, or only the check that parseScene
/// makes of "receivers" (every key and value, the geometry entries it names, the output's
/// extension), for which it loads nothing and returns null.
enum class KindUse : uint8_t { Bake, Validate };

/// @brief Everything a factory gets: the "receivers" object (strict: finish() is called by the
/// registry after the factory returns, so a factory reads every key before it returns, in either
/// use), the scene (its folder, geometry list, lights) and the use. It returns null for
/// KindUse::Validate.
using ReceiverKindFactory =
    std::function<std::unique_ptr<ReceiverKind>(const JsonParams& params, const SceneDesc& scene, KindUse use)>;

/// @brief The files a kind always writes beside output @p output, named after it (a camera's
/// preview: previewPath()). The kind's writer names them with the same function.
using DerivedOutputs = std::vector<std::string> (*)(const std::string& output);

/// @brief Registers (or replaces) receiver type @p type, whose outputs default to
/// @p outputExtension when the scene names none (`out/shadows.vdb` for a volume).
/// @param derived the files the kind always writes beside its output, so that they are checked
///        with the other outputs before any work (BakeOutputs.h); null: none
void registerReceiverKind(const std::string& type, ReceiverKindFactory factory, std::string outputExtension = ".exr",
                          DerivedOutputs derived = nullptr);

/// @brief The files the kind of @p scene always writes beside its output, named after it
/// (registerReceiverKind()'s DerivedOutputs): "out/a.png" for a camera's "out/a.exr".
std::vector<std::string> receiverKindDerivedOutputs(const SceneDesc& scene);

/// @brief The output extension of the kind the "receivers" object names (".exr" when the type is
/// unknown or missing: makeReceiverKind() reports that).
std::string receiverKindExtension(const nlohmann::json& receivers);

/// @brief Makes the kind named by the object's "type" key, once per bake.
/// @throw InputError naming the key for an unknown type or bad parameters.
std::unique_ptr<ReceiverKind> makeReceiverKind(const nlohmann::json& receivers, const SceneDesc& scene);

/// @brief Checks "receivers" as makeReceiverKind() would, without making the kind or loading
/// what it names (parseScene).
/// @throw InputError as makeReceiverKind().
void validateReceiverKind(const nlohmann::json& receivers, const SceneDesc& scene);

/// @brief Registers a receiver type from the kind's own file, as a namespace-scope constant
/// (`const ReceiverKindRegistration kCamera{"camera", &makeCameraKind};`), so that no central
/// file lists the kinds. The library is linked whole (CMakeLists.txt) so that none is dropped.
struct ReceiverKindRegistration {
    ReceiverKindRegistration(const std::string& type, ReceiverKindFactory factory, std::string outputExtension = ".exr",
                             DerivedOutputs derived = nullptr) {
        registerReceiverKind(type, std::move(factory), std::move(outputExtension), derived);
    }
};

/// @brief Refuses an output whose extension (any case) is none of @p extensions: the extension
/// names the format, and a kind writes only its own (`-o x.tiff` or `-o x.png` of a camera bake).
/// @param oneFile the kind writes that one file and nothing named after it (points, volume): then
///        a character device or FIFO (`-o /dev/null`) is accepted too, and written into
/// @throw InputError naming the output ("--output" when -o gave it) and the formats the kind writes.
void requireOutputExtension(const SceneDesc& scene, const std::vector<std::string>& extensions, const std::string& kind,
                            bool oneFile = false);

/// @brief A path from a scene file resolved against the scene's folder, which it must not leave
/// (SafePath.h; `--allow-outside-uris` lifts the rule). @p where names the key in messages.
/// @throw InputError naming @p where (or the path) when the path leaves the folder.
std::string resolveScenePath(const std::filesystem::path& baseDir, const std::string& path, const std::string& where = "");

}  // namespace penumbra
