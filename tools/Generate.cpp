#include "Generate.h"

#include "bake/BakeOutputs.h"
#include "stream/util/Timer.h"
#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "stream/util/Error.h"
#include "stream/GeometryFile.h"
#include "stream/ProgressSource.h"
#include "stream/util/Progress.h"
#include "stream/util/InputFile.h"

#include <fmt/format.h>
#include <tbb/global_control.h>

#include <chrono>
#include <memory>

namespace penumbra {

CLI::App* addGenerateCommand(CLI::App& app, GenerateOptions& options) {
    CLI::App* cmd = app.add_subcommand("generate", "write a scene's geometry (generated and loaded) to .ptri, .obj or .glb/.gltf");
    cmd->add_option("scene", options.scene, "scene file (JSON)")->required();
    cmd->add_option("-o,--output", options.output, "output file; the format follows the extension")->required();
    cmd->add_option("--threads", options.threads, "worker threads (default: all cores); the output is the same for any value");
    cmd->add_flag("-q,--quiet", options.quiet, "no progress or summary on stderr");
    return cmd;
}

uint64_t runGenerate(const GenerateOptions& options) {
    if (options.threads < 0 || options.threads > kMaxThreads)
        throw InputError(fmt::format("--threads: must be in 0..{} (0: all cores), got {}", kMaxThreads, options.threads));
    if (options.output.empty()) throw InputError("--output: must not be empty");
    InputScope inputs;  // the output must not replace a file the scene reads
    // Generators split chunks across TBB workers; this caps how many there are.
    std::unique_ptr<tbb::global_control> limit;
    if (options.threads > 0)
        limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(options.threads));

    const Stopwatch watch;
    SceneDesc scene = loadScene(options.scene);
    checkOutputAgainstInputs(scene, options.output);
    TriangleSourcePtr source;
    {
        OpeningProgress opening(options.quiet);  // a large OBJ's check pass: [check mesh.obj]
        source = openSceneGeometryForExport(scene);
    }
    // Generation and the write are one pass, shown as a phase: a billion blades take minutes.
    source = std::make_unique<ProgressSource>(std::move(source), "generate", options.quiet);
    convertGeometry(*source, options.output);
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

}  // namespace penumbra
