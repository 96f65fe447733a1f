#include "bake/SceneAlpha.h"
#include "Generate.h"

#include "bake/BakeMemory.h"
#include "bake/BakeOutputs.h"
#include "stream/util/Timer.h"
#include "bake/TbbControl.h"
#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "stream/util/Error.h"
#include "stream/GeometryFile.h"
#include "stream/ProgressSource.h"
#include "stream/util/Progress.h"
#include "stream/util/InputFile.h"
#include "stream/util/Memory.h"
#include "stream/util/PathText.h"

#include <fmt/format.h>

#include <chrono>
#include <algorithm>
#include <memory>
#include <thread>
#include <string>

namespace penumbra {

CLI::App* addGenerateCommand(CLI::App& app, GenerateOptions& options) {
    CLI::App* cmd = app.add_subcommand("generate", "write a scene's geometry (generated and loaded) to .ptri, .obj or .glb/.gltf");
    cmd->add_option("scene", options.scene, "scene file (JSON)")->required();
    cmd->add_option("-o,--output", options.output, "output file; the format follows the extension")->required();
    cmd->add_option("--threads", options.threads, "worker threads (default: all cores); the output is the same for any value");
    cmd->add_flag("-q,--quiet", options.quiet, "no progress or summary on stderr");
    return cmd;
}

namespace {

/// Counts the triangles of the last pass that carry an alpha outline (alphaIdOf()).
class CutoutCount final : public DecoratedSource {
public:
    using DecoratedSource::DecoratedSource;
    size_t read(std::span<Triangle> out) override {
        const size_t n = inner_->read(out);
        for (size_t i = 0; i < n; ++i) count_ += alphaIdOf(out[i].flags) != 0;
        return n;
    }
    void rewind() override { inner_->rewind(), count_ = 0; }
    uint64_t count() const { return count_; }

private:
    uint64_t count_ = 0;
};

/// Under an address-space limit, whether the opened sources' working sets (a scatter's kept
/// source, a forest's variants, terrain heights: built on the first read) fit, before any is
/// built: without this, generating failed with a bare "out of memory" at any limit.
/// @throw InputError naming a limit that works.
void checkGenerateFits(const TriangleSource& source, const BakeBudget& budget, const std::string& scene) {
    if (budget.bytes == 0) return;
    // The read-ahead and the writer's chunks, as a bake's scan counts them.
    const uint64_t needed = kBaselineBytes + source.residentBytes() + 8 * kTriangleChunk * sizeof(Triangle);
    if (needed <= budget.bytes) return;
    const std::string detail = source.residentDetail();
    throw InputError(fmt::format("{}: {} {} is too small to generate this geometry; at least {} is needed{}", scene, budget.label,
                                 formatBytes(budget.bytes + budget.overhead), budgetText(needed + budget.overhead + budget.namedSlack),
                                 detail.empty() ? "" : " (" + detail + ")"));
}

/// One attempt at the whole command with options.threads workers.
uint64_t generateOnce(const GenerateOptions& options) {
    InputScope inputs;  // the output must not replace a file the scene reads
    // Generators split chunks across TBB workers; this caps how many there are. Under an
    // address-space limit, as many as leave the bake's room (as a bake plans them), with the
    // bake's worker stacks: at 64 MiB two threads could not start.
    int threads = options.threads;
    BakeBudget budget;
    if (addressSpaceLimit() != 0) {
        if (threads == 0) threads = int(std::max(1u, std::thread::hardware_concurrency()));
        budget = fitAddressSpace(0, threads, options.quiet);
    }
    const ScopedTbbControl limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
    const ScopedTbbControl stacks(tbb::global_control::thread_stack_size, threads > 1 && addressSpaceLimit() != 0 ? size_t(kWorkerStackBytes) : 0);

    const Stopwatch watch;
    checkGeometryOutputExtension(options.output);  // before the scene's warnings and the work
    SceneDesc scene = loadScene(options.scene);
    checkOutputAgainstInputs(scene, options.output);
    warnExportDrops(scene);  // what a geometry file cannot hold, before the work
    TriangleSourcePtr source;
    {
        OpeningProgress opening(options.quiet);  // a large OBJ's check pass: [check mesh.obj]
        source = openSceneGeometryForExport(scene);
    }
    checkGenerateFits(*source, budget, options.scene);
    // Generation and the write are one pass, shown as a phase: a billion blades take minutes.
    source = std::make_unique<ProgressSource>(std::move(source), "generate", options.quiet);
    auto counted = std::make_unique<CutoutCount>(std::move(source));
    CutoutCount& cutouts = *counted;
    source = std::move(counted);
    convertGeometry(*source, options.output);
    // Only .ptri holds a triangle's outline: petals and leaves written to .obj or glTF block as
    // whole triangles when the file is baked (the bake of the generators cuts them).
    if (cutouts.count() && lowercaseExtension(options.output) != ".ptri")
        printWarning("{}: {} cut-out triangles (petal and leaf outlines) written as plain ones: {} holds no outlines, so baked "
                     "from this file they block as whole triangles; write .ptri to keep them",
                     options.output, cutouts.count(), lowercaseExtension(options.output));
    // convertGeometry does not report a count; the stream's size is known for every generator,
    // and for files it equals what was written, so ask the source rather than reading it again.
    uint64_t written = source->sizeHint().value_or(0);
    if (!source->sizeHint()) written = scanGeometry(*source).triangles;
    if (!options.quiet) {
        const double seconds = watch.seconds();
        fmt::print(stderr, "penumbra: {} triangles -> {} ({:.2f} s)\n", written, options.output, seconds);
    }
    return written;
}

}  // namespace

uint64_t runGenerate(const GenerateOptions& options) {
    if (options.threads < 0 || options.threads > kMaxThreads)
        throw InputError(fmt::format("--threads: must be in 0..{} (0: all cores), got {}", kMaxThreads, options.threads));
    if (options.output.empty()) throw InputError("--output: must not be empty");
    try {
        return generateOnce(options);
    } catch (const std::exception& e) {
        // TBB could not start its workers (an address-space or process limit): the output is
        // written as a whole or not at all, and its bytes do not depend on the thread count, so
        // generate again on one thread, which starts none (as a bake does).
        if (!retryOnOneThread(e, options.threads, "generating")) throw;
        GenerateOptions one = options;
        one.threads = 1;
        return generateOnce(one);
    }
}

}  // namespace penumbra
