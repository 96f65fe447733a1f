#include "FileCommands.h"

#include "bake/BakeOutputs.h"
#include "bake/TbbControl.h"
#include "bake/output/VolumeSlice.h"
#include "stream/GeometryFile.h"
#include "stream/ProgressSource.h"
#include "stream/util/Error.h"
#include "stream/util/PathText.h"

#include <fmt/format.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

namespace penumbra {
namespace {

/// Writes a command's result to stdout; a failed write (a full disk, a closed pipe) is an error,
/// since the result is what the command is for.
void printResult(const std::string& text) {
    if (std::fwrite(text.data(), 1, text.size(), stdout) != text.size() || std::fflush(stdout) != 0)
        throw InputError(fmt::format("stdout: write failed: {}", std::strerror(errno)));
}

int runCompare(const CompareOptions& options) {
    CompareResult r = compareDumps(options);
    printResult(fmt::format("receivers {}\nsamples {}\nrelations {}\nblocked_a {}\nblocked_b {}\nonly_a {}\nonly_b {}\n",
                            r.receivers, r.samples, r.relations, r.blockedA, r.blockedB, r.onlyA, r.onlyB));
    if (r.classified) {
        printResult(fmt::format("ties {}\nunexplained {}\n", r.ties, r.unexplained()));
        for (const auto& [quantity, count] : r.tiesByQuantity) printResult(fmt::format("ties_{} {}\n", quantity, count));
    }
    const bool same = r.classified ? r.unexplained() == 0 : r.onlyA + r.onlyB == 0;
    return same ? 0 : 3;
}

void runInfo(const std::string& path, bool quiet) {
    TriangleSourcePtr source;
    {
        OpeningProgress opening(quiet);  // a large OBJ's check pass: [check mesh.obj]
        source = openGeometryFile(path);
    }
    // The pass over the triangles, a phase of its own: a 20 GB file takes minutes.
    ProgressSource shown(std::move(source), "read " + std::filesystem::path(path).filename().string(), quiet);
    GeometryInfo g = scanGeometry(shown);
    printResult(fmt::format("triangles {}\nbounds_min {} {} {}\nbounds_max {} {} {}\narea {}\n", g.triangles, g.lo.x, g.lo.y,
                            g.lo.z, g.hi.x, g.hi.y, g.hi.z, g.area));
}

}  // namespace

void addFileCommands(CLI::App& app, FileCommands& c) {
    c.compareCommand = app.add_subcommand("compare", "compare two --dump directories relation by relation");
    c.compareCommand->add_option("dump_a", c.compare.dirA)->required();
    c.compareCommand->add_option("dump_b", c.compare.dirB)->required();
    c.compareCommand->add_option("--scene", c.compare.scenePath, "scene file: classify mismatches as ties of the blocking rule");
    c.compareCommand->add_option("--list", c.compare.list, "print this many mismatches with their verdicts (default 10)");
    c.compareCommand->add_option("--mismatches", c.compare.mismatchesCsv, "write every mismatch and its verdict as CSV");

    c.infoCommand = app.add_subcommand("info", "print triangle count, bounds and total area of a geometry file");
    c.infoCommand->add_option("file", c.infoPath)->required();
    c.infoCommand->add_flag("-q,--quiet", c.infoQuiet, "no progress on stderr");

    c.convertCommand = app.add_subcommand("convert", "convert geometry between .obj, .gltf/.glb and .ptri");
    c.convertCommand->add_option("input", c.convertIn)->required();
    c.convertCommand->add_option("output", c.convertOut)->required();
    c.convertCommand->add_flag("-q,--quiet", c.convertQuiet, "no progress on stderr");

    c.sliceCommand = app.add_subcommand("vdb-slice", "render an axis-aligned slice of a .vdb float grid to a PNG");
    c.sliceCommand->add_option("input", c.sliceIn)->required();
    c.sliceCommand->add_option("output", c.sliceOut)->required();
    c.sliceCommand->add_option("--axis", c.sliceAxis, "x, y or z")->required()->check(CLI::IsMember({"x", "y", "z"}));
    c.sliceCommand->add_option("--at", c.sliceAt, "world coordinate of the slice along the axis")->required();
    c.sliceCommand->add_option("--grid", c.sliceGrid, "float grid name");
}

std::optional<int> runFileCommand(const FileCommands& c, std::string& context) {
    if (*c.compareCommand) return context = c.compare.dirA, runCompare(c.compare);
    if (*c.infoCommand) {
        context = c.infoPath;
        runInfo(c.infoPath, c.infoQuiet);
        return 0;
    }
    if (*c.convertCommand) {
        context = c.convertIn;
        convertGeometryFile(c.convertIn, c.convertOut, c.convertQuiet);
        return 0;
    }
    if (*c.sliceCommand) {
        context = c.sliceIn;
        // As every other command: no folders made for a path typed by hand, and the name says PNG.
        if (lowercaseExtension(c.sliceOut) != ".png") fail(c.sliceOut, "vdb-slice writes a PNG: name the output .png");
        requireOutputFolder("output", c.sliceOut);
        // One thread under an address-space limit: OpenVDB reads with TBB, whose workers could
        // not start at 155-160 MiB and aborted the process after the PNG was written.
        const ScopedTbbControl one(tbb::global_control::max_allowed_parallelism, addressSpaceLimit() != 0 ? 1 : 0);
        writeVolumeSlicePng(c.sliceIn, c.sliceOut, c.sliceGrid, c.sliceAxis[0], c.sliceAt);
        return 0;
    }
    return std::nullopt;
}

}  // namespace penumbra
