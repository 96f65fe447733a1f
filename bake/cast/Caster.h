#pragma once
/// @file Caster.h
/// @brief The one interface every shadow method implements (`--method`): cast a replayable
/// stream of blockers against receivers and light samples, and report each receiver's result.
///
/// Methods register themselves by name (CasterRegistration in their own .cpp, so that no central
/// file lists them), with their traits: whether they stream or hold the scene, want the
/// largest-first replay of the bucket pass, give per-sample masks or only visible fractions, and
/// what they hold in memory. The pipeline (bake/Pipeline.cpp) only ever sees this interface.

#include "bake/cast/CastOptions.h"
#include "bake/cast/VisibilityMasks.h"
#include "bake/light/Light.h"
#include "receivers/ReceiverSet.h"
#include "stream/util/JsonParams.h"
#include "stream/Triangle.h"
#include "stream/TriangleSource.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

struct ReceiverPolygons;  // bake/kinds/ReceiverKind.h: the lightmap texels' triangles

/// @brief Where a caster reports results; called concurrently for different receivers.
struct CastSink {
    /// Exact methods: @p groupWords holds one word per light sample group (nullptr: nothing
    /// blocked), @p fullUmbra means every sample is blocked.
    std::function<void(uint32_t receiver, const uint64_t* groupWords, bool fullUmbra)> masks;
    /// Methods that weigh translucent blockers themselves (CasterTraits::translucency): the
    /// masks as above and @p depth, the receiver's per-sample R, G, B optical depths
    /// (stream/Translucency.h; sampleCount x 3), or nullptr where none was crossed.
    std::function<void(uint32_t receiver, const uint64_t* groupWords, bool fullUmbra, const uint32_t* depth)> masksWithDepth;
    /// Methods without per-sample masks: the visible fraction of each light, lightCount() floats.
    std::function<void(uint32_t receiver, const float* lightVisibility)> visibility;
};

/// @brief A memory tile's cast so far (a checkpoint within a tile): the masks of its receivers
/// (row i for the tile's i-th receiver) after the first `replayed` blockers of the replay, whose
/// bytes hash to `replayHash`. Masks are an OR over blockers, so casting the rest of the replay
/// and ORing it in gives exactly the masks of an uninterrupted cast.
struct TileProgress {
    uint64_t replayed = 0, replayHash = 0;
    VisibilityMasks masks;
};

/// @brief What a bake asks of a method's memory tiles in its first pass (bake/shard: shards and
/// checkpoints). A method without tiles ignores them and casts every receiver.
struct TileHooks {
    /// The receivers this bake casts among @p ids (a shard's part), or empty: all of them.
    std::function<std::vector<uint32_t>(std::vector<uint32_t> ids)> select;
    /// Tile @p tile of @p tiles (receivers @p ids) was restored and reported already: skip it.
    std::function<bool(size_t tile, size_t tiles, std::span<const uint32_t> ids)> restore;
    /// Tile @p tile of @p tiles is cast and every one of its receivers reported to the sink.
    std::function<void(size_t tile, size_t tiles, std::span<const uint32_t> ids)> finished;
    /// Checkpoints within a tile (all three set, or none):
    /// the saved progress of tile @p tile, if any, to continue from;
    std::function<std::optional<TileProgress>(size_t tile, size_t tiles, std::span<const uint32_t> ids)> resume;
    /// whether the tile in progress should be saved now (`--checkpoint-every`);
    std::function<bool()> progressDue;
    /// save it.
    std::function<void(size_t tile, size_t tiles, std::span<const uint32_t> ids, const TileProgress& progress)> saveProgress;
    /// The replay does not start with the blockers a resumed progress holds: refuse it (throws
    /// under `--resume`) or note it; the tile is then cast from the start.
    std::function<void(size_t tile, size_t tiles)> rejectProgress;
};

/// @brief Everything a method needs to cast, fixed for the bake.
struct CastContext {
    const LightSamples& samples;
    const ReceiverSet& receivers;  ///< every receiver of the bake (refinement ones appended)
    const std::vector<uint32_t>& sampleSets;  ///< grows with the receivers on refinement
    const CastOptions& options;    ///< the scene's, with the rule's epsilon length set
    const nlohmann::json& methodOptions;  ///< the scene's "bake" object, for method-specific keys
    int threads = 1;
    int memoryTiles = 1;           ///< hpc: receiver tiles cast one after another (--memory-budget)
    bool quiet = false;
    /// Sees every blocker chunk once during the first cast (a receiver kind's cast pass), or empty.
    std::function<void(std::span<const Triangle>)> observeChunk;
    const ReceiverPolygons* polygons = nullptr;  ///< lightmap receivers' polygons, when the kind has them
    const TileHooks* tileHooks = nullptr;        ///< for the first cast (receivers from 0), or null
    int subTilesPerThread = 4;                   ///< hpc: sub-tiles per thread in a memory tile (MemoryPlan)
};

/// @brief One bake's method.
class Caster {
public:
    virtual ~Caster() = default;
    /// @brief Casts receivers [@p first, end) against @p blockers, which the caster may rewind
    /// and read as often as it needs; reports each of those receivers exactly once to @p sink.
    virtual void cast(TriangleSource& blockers, uint32_t first, const CastSink& sink) = 0;
    /// @brief The paper's counters and timers, summed over every cast() so far.
    virtual CastStats stats() const { return {}; }
    /// @brief The method's own stats (for the stats JSON under its name), or null.
    virtual nlohmann::json methodStats() const { return nullptr; }
};

/// @brief Calls @p report for receivers [@p first, @p end) on the worker threads (the sink's
/// calls are concurrent by contract: shading each receiver is independent of the others).
void reportInParallel(uint32_t first, uint32_t end, const std::function<void(uint32_t)>& report);

/// @brief What the pipeline must know of a method before it casts.
struct CasterTraits {
    bool exact = true;          ///< the rule's masks, up to classified ties
    bool masks = true;          ///< reports per-sample masks (else visible fractions only)
    bool sortedBlockers = true; ///< wants the largest-first replay of the bucket pass
    bool holdsScene = false;    ///< reads every blocker into memory (ray casters)
    bool needsPolygons = false; ///< needs the receiver kind's polygons (lightmaps)
    /// Casts translucent triangles itself (Embree's filter) and reports through
    /// CastSink::masksWithDepth; otherwise they reach the method as non-casting and the pipeline
    /// weighs them (bake/cast/TranslucentBlockers.h).
    bool translucency = false;
    /// Casts receivers in memory tiles (hpc): only such a method checkpoints its tiles and can
    /// be sharded by receivers.
    bool memoryTiles = false;
    const char* summary = "";   ///< one line for --help
};

/// @brief Bytes a method holds beyond the common memory plan, for @p triangles blockers and
/// @p receivers receivers (the first pass's).
using CasterMemory = std::function<uint64_t(uint64_t triangles, uint64_t receivers, const LightSamples& samples,
                                            const nlohmann::json& methodOptions)>;
using CasterFactory = std::function<std::unique_ptr<Caster>(const CastContext& context)>;

struct CasterEntry {
    std::string name;
    CasterTraits traits;
    CasterFactory make;
    CasterMemory memory;  ///< optional
    /// Reads and validates the method's keys of the scene's "bake" object (optional), so that its
    /// finish() accepts them whichever method bakes; throws InputError naming the key.
    std::function<void(const JsonParams& bake)> checkOptions;
};

/// @brief Registers a method at static-initialization time: `static CasterRegistration r{{...}};`
struct CasterRegistration {
    explicit CasterRegistration(CasterEntry entry);
};

/// @brief The method named @p name.
/// @throw InputError ("--method: unknown method ... (known: ...)") for an unknown name.
const CasterEntry& casterEntry(const std::string& name);

/// @brief Refuses a scene with "max_distance" blockers for method @p method, which does not
/// apply the distance test (hpc, reference, embree and ssv do: AlphaRule.h).
/// @throw InputError "--method ssv: ...".
void refuseMaxDistance(const CastContext& context, const std::string& method);

/// @brief Every registered method's name, in the order they are listed (hpc first).
std::vector<std::string> casterNames();

}  // namespace penumbra
