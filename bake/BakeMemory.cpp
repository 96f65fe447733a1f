#include "bake/BakeMemory.h"

#include "bake/cast/ClosedExemptions.h"
#include "bake/cast/PenumbraCaster.h"
#include "bake/cast/SampleMaskTable.h"
#include "bake/cast/TileCaster.h"
#include "bake/light/SunLight.h"
#include "bake/SceneAlpha.h"
#include "bake/WorkPlan.h"
#include "bake/kinds/ReceiverKind.h"
#include "bucket/BucketOptions.h"
#include "stream/GltfReader.h"
#include "stream/util/PathText.h"
#include "stream/util/Error.h"
#include "stream/util/Memory.h"
#include "stream/util/Progress.h"
#include "stream/PrefetchSource.h"

#include <fmt/format.h>

#include <cstdio>

namespace penumbra {

void warnFewerThreads(const BakeBudget& budget, bool quiet) {
    if (budget.threads < budget.threadsWanted && !quiet)
        fmt::print(stderr, "penumbra: warning: the address-space limit of {} leaves room for {} thread{} (of {})\n",
                   formatBytes(addressSpaceLimit()), budget.threads, budget.threads == 1 ? "" : "s", budget.threadsWanted);
}

BakeBudget fitAddressSpace(uint64_t memoryBudget, int& threads, bool quiet, int asked) {
    BakeBudget budget;
    budget.bytes = memoryBudget;
    budget.threads = threads, budget.threadsWanted = asked > 0 ? asked : threads;
    const uint64_t limit = addressSpaceLimit();
    if (limit == 0) return budget;
    useOneMallocArena();
    // Mapped but not resident: the libraries (OpenVDB and Embree alone map about 100 MiB) and
    // reserved stacks. The baseline of the plan stands for what is resident of it.
    const uint64_t mapped = mappedNotResidentBytes() + 2 * kReadAheadStackBytes + (16ull << 20);
    auto room = [&](int n) { return int64_t(limit) - int64_t(mapped) - int64_t(n - 1) * int64_t(kWorkerStackBytes); };
    const int wanted = budget.threadsWanted;
    // Keep at least the baseline and a little for the bake's own data per thread.
    while (threads > 1 && room(threads) < int64_t(kBaselineBytes + (16ull << 20) * uint64_t(threads))) --threads;
    budget.threads = threads;
    warnFewerThreads(budget, quiet);
    const int64_t left = std::max<int64_t>(room(threads), 0);
    budget.overhead = limit - uint64_t(left);
    // A limit below what is mapped leaves nothing (left is 0), and the overhead is then the limit
    // itself: the shortfall goes into the slack, or 64M named 16 MiB less than 80M did.
    budget.namedSlack = uint64_t(wanted - threads) * kWorkerStackBytes + kMappedJitterBytes + uint64_t(std::max<int64_t>(-room(threads), 0));
    budget.bytes = memoryBudget ? std::min<uint64_t>(memoryBudget, uint64_t(left)) : uint64_t(left);
    if (!memoryBudget || uint64_t(left) < memoryBudget) budget.label = "the address-space limit (prlimit --as, ulimit -v) of";
    else budget.overhead = 0, budget.namedSlack = 0;
    return budget;
}

void addSampleDemand(MemoryDemand& demand, const LightSamples& samples, const SceneDesc& scene) {
    demand.groups = samples.groupCount();
    demand.umbraWords = (demand.groups + 63) / 64;
    const uint64_t positions = uint64_t(samples.sets) * uint64_t(samples.sampleCount);  // a layout holds none yet
    demand.sampleBytes = positions * sizeof(glm::vec3);
    // generateLightSamples(): the float positions (12), each light's points gathered as doubles
    // for its bound (24), their 2D copies for the hull, passed by value, and its output (3 x 16),
    // and the allocator's rounding; measured 105 MB for a million positions.
    demand.sampleBuildBytes = positions * 104;
    demand.subTileBytes = TileCaster::fixedBytes(samples);
    if (scene.options.sampleTable)  // one copy per caster; casters (memory tiles) run one at a time
        for (uint32_t l = 0; l < uint32_t(samples.lightCount()); ++l)
            demand.sampleBytes +=
                SampleMaskTable::plannedBytes(samples, l, scene.options.sampleTableAngles, scene.options.sampleTableOffsets);
}

MemoryDemand demandBeforeScan(const SceneDesc& scene, const ReceiverKind& kind, const TriangleSource& geometry, MaskKeeping masks,
                              const CasterMemory& methodMemory, bool alpha) {
    MemoryDemand d;
    d.dumpMasks = masks.kept;
    d.scanBytes = kind.passBytes(StreamPass::Scan);
    d.receivers = kind.receiverBound().value_or(0);
    if (masks.shares > 1) d.castReceivers = d.maskRows = (d.receivers + masks.shares - 1) / masks.shares;  // 0 while unknown: all
    d.kindBytes = kind.maxResidentBytes(d.receivers, geometry.knownSize());
    d.outputBytes = kind.outputBytes(d.receivers);
    // The sources read ahead on a thread of their own (PrefetchSource: 4 chunks queued, one being
    // filled, one handed out).
    d.sourceBytes = geometry.residentBytes() + 6 * kTriangleChunk * sizeof(Triangle);
    d.sourceDetail = geometry.residentDetail();
    d.sourceDuringCast = !scene.options.sortBlockers;
    if (const GltfAlphaState* state = alpha ? planSceneAlpha(scene) : nullptr)
        d.alphaBytes = state->tableBytes, d.alphaBuildBytes = state->buildBytes;
    const LightSamples samples = lightSampleLayout(scene.lights, scene.options.groupSize);
    addSampleDemand(d, samples, scene);
    if (const std::optional<uint64_t> triangles = geometry.knownSize(); methodMemory && triangles)
        d.methodBytes = methodMemory(*triangles, d.receivers, samples, scene.bakeOptions);
    // Bucket buffers, the replay's read-ahead queue and the caster's ring of prepared chunks, and
    // with closed casters the ring of the caster for the receivers they must not skip for.
    const BucketOptions buckets;
    d.bufferBytes = (scene.options.sortBlockers ? buckets.writeMemoryBytes() + buckets.readBufferBytes : 0) +
                    8 * kTriangleChunk * sizeof(Triangle) +
                    PenumbraCaster::kMaxRingChunks * PenumbraCaster::preparedChunkBytes(scene.lights.size()) +
                    (scene.options.closedCasters ? closedExemptCasterBytes(scene.lights.size()) : 0);
    return d;
}

uint64_t leastNamedLimit(const MemoryDemand& demand, const BakeBudget& budget) {
    // Under an address-space limit, at least what the scan pass will be asked for after this
    // (checkAddressSpaceLeft): the plan's overhead was measured before the volume plugin loaded,
    // and a limit this named (216M) was then refused again, naming 239 MiB. And the stacks of
    // the threads the limit left out, which a larger limit runs (200M named 240M, then 244M).
    uint64_t least = planMemory(demand, 0).minimumBudget + budget.overhead;
    if (budget.overhead != 0) least = std::max(least, addressSpaceNeeded(scanPhaseBytes(demand)));  // the limit is the budget
    return least + budget.namedSlack;
}

void checkBeforeScan(const MemoryDemand& demand, const BakeBudget& budget) {
    if (budget.bytes == 0) return;
    const MemoryPlan worst = planMemory(demand, 0);
    if (budget.bytes >= scanPhaseBytes(demand)) return;  // the scan fits; the exact check follows it
    std::string why;
    if (!demand.sourceDetail.empty() && demand.sourceBytes > worst.minimumBudget / 2) why = fmt::format(" ({})", demand.sourceDetail);
    const uint64_t least = leastNamedLimit(demand, budget);
    // Receivers a kind finds only in its scan (a mesh's vertices) are not counted yet.
    const std::string what =
        demand.receivers > 0 ? fmt::format("up to {} receivers of {} light-sample groups each", demand.receivers, demand.groups)
                             : fmt::format("the passes before the receivers are counted ({} light-sample groups each)", demand.groups);
    std::string message = fmt::format("{} {} is too small for {}; at least {} is needed{}", budget.subject(),
                                      refusedBudgetText(budget.bytes + budget.overhead), what, budgetText(least), why);
    if (budget.addressSpace() && budget.threads > 1) {
        // Each thread fewer leaves its stack's room to the bake: one try with as many fewer as
        // the shortfall needs (not one at a time: every try opens the geometry again).
        const uint64_t shortfall = scanPhaseBytes(demand) - budget.bytes;
        const uint64_t fewer = std::max<uint64_t>(1, (shortfall + kWorkerStackBytes - 1) / kWorkerStackBytes);
        throw ThreadsDoNotFit(message, int(std::max<int64_t>(1, int64_t(budget.threads) - int64_t(fewer))));
    }
    throw InputError(message);
}

namespace {

/// The largest opening among the scene's glTF files (gltfOpeningBytes()) and its file: opening
/// holds it before the plan made after the opening can refuse anything.
std::pair<GltfOpeningBytes, std::string> gltfOpeningPeak(const SceneDesc& scene) {
    std::pair<GltfOpeningBytes, std::string> most{{}, {}};
    for (const GeometryDesc& g : scene.geometry) {
        if (!g.params.contains("path") || !g.params["path"].is_string()) continue;
        std::string path;
        try {
            path = resolveScenePath(scene.baseDir, g.params["path"].get<std::string>());
        } catch (const InputError&) {
            continue;  // opening says why
        }
        const std::string extension = lowercaseExtension(path);
        if (extension != ".gltf" && extension != ".glb") continue;
        if (const GltfOpeningBytes bytes = gltfOpeningBytes(path); bytes.total() > most.first.total()) most = {bytes, path};
    }
    return most;
}

/// A budget that cannot hold the largest glTF's parse is refused before it is parsed: the refusal
/// after the opening peaked at 124 MB under --memory-budget 32M (8.6 MiB of JSON), which a job
/// capped at its budget does not survive. The plan after the opening still checks the rest.
void checkParsingFits(const SceneDesc& scene, const ReceiverKind& kind, const BakeBudget& budget, MaskKeeping masks,
                      const CasterMemory& methodMemory) {
    if (budget.bytes == 0) return;
    const auto [opening, file] = gltfOpeningPeak(scene);
    if (opening.parse < TriangleSource::kNotableResidentBytes) return;
    uint64_t openingBytes = opening.total();
    std::string detail = fmt::format("{}: its glTF JSON takes about {} to parse", file, formatBytes(opening.parse));
    if (opening.held) detail += fmt::format(" and {} to hold", formatBytes(opening.held));
    // Under an address-space limit the parse's text and tree stay mapped once freed (the heap
    // and the threads' arenas keep them; the plan after the opening measures what is mapped):
    // for 300,000 nodes in 15.8 MiB, 498M named before the opening became 788M after it, and
    // with the parse counted twice, 703M became 839M. Three times names enough at once.
    if (budget.overhead) openingBytes += 2 * opening.parse, detail += ", which stays mapped under an address-space limit";
    const VectorSource none({});
    MemoryDemand before = demandBeforeScan(scene, kind, none, masks, methodMemory, /*alpha=*/false);
    before.threads = budget.threads;
    before.sourceBytes += openingBytes;
    before.sourceDetail = detail;
    checkBeforeScan(before, budget);
}

}  // namespace

TriangleSourcePtr openCheckedBeforeScan(const SceneDesc& scene, const ReceiverKind& kind, const BakeBudget& budget, MaskKeeping masks,
                                        bool quiet, MemoryDemand& demand,
                                        const CasterMemory& methodMemory) {
    checkParsingFits(scene, kind, budget, masks, methodMemory);  // before the alpha plan and the opening parse glTF
    // Before a texture is decoded (opening builds the table); its refusal names at least what the
    // plan before the scan will ask for, sources aside.
    uint64_t leastOtherwise = 0;
    if (budget.bytes > 0) {
        const VectorSource none({});
        MemoryDemand rough = demandBeforeScan(scene, kind, none, masks, methodMemory, /*alpha=*/false);
        rough.threads = budget.threads;
        leastOtherwise = leastNamedLimit(rough, budget);
    }
    checkSceneAlphaBudget(scene, budget.bytes, budget.label, budget.overhead, budget.namedSlack, leastOtherwise);
    TriangleSourcePtr geometry = [&] {
        OpeningProgress opening(quiet);  // an OBJ's check pass shows as a phase
        return openSceneGeometry(scene);
    }();
    demand = demandBeforeScan(scene, kind, *geometry, masks, methodMemory);
    demand.threads = budget.threads;
    checkBeforeScan(demand, budget);
    return geometry;
}

}  // namespace penumbra
