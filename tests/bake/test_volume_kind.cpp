// The "volume" receiver kind: the VDB read back through OpenVDB matches a points bake of the same
// voxel centres exactly, lit and umbra regions are tiles, narrow bands follow the geometry.

#include "CliRunner.h"

#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "stream/SourceRegistry.h"
#include "stream/util/Npy.h"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include <catch2/catch.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cstring>
#include <fstream>

using namespace penumbra;
using namespace penumbra::test;

namespace {

const std::string kFloor = std::string(PENUMBRA_SOURCE_DIR) + "/examples/vertices-floor.glb";

/// The example floor (y = 0, 6 x 6) with a 1.2-wide blocker at y = 1.2..1.5, under a small light.
nlohmann::json sceneJson(const nlohmann::json& receivers, const std::string& output) {
    return {{"geometry", {{{"type", "glb"}, {"path", kFloor}}}},
            {"lights", {{{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {0.5, 0, 0}}, {"v", {0, 0, 0.5}}, {"samples", 64},
                         {"sample_sets", 4}}}},
            {"receivers", receivers},
            {"output", output}};
}

void bake(const ScratchDir& dir, const nlohmann::json& scene) {
    registerFileSourceTypes();
    AllowOutsidePaths examples;  // the scene in the scratch directory bakes the examples' floor
    BakeSettings settings;
    settings.quiet = true;
    settings.threads = 2;
    runBake(parseScene(scene, dir / "scene.json"), settings);
}

openvdb::GridBase::Ptr readGrid(const std::string& path, const std::string& name) {
    openvdb::initialize();
    openvdb::io::File file(path);
    file.open();
    REQUIRE(file.hasGrid(name));
    openvdb::GridBase::Ptr grid = file.readGrid(name);
    file.close();
    return grid;
}

/// The visibility grid of a band of @p width around the floor entry, at voxel_size 0.1.
openvdb::FloatGrid::Ptr bakeBand(const ScratchDir& dir, double width) {
    bake(dir, sceneJson({{"type", "volume"}, {"narrow_band", {{"geometry", {0}}, {"width", width}}}, {"voxel_size", 0.1}},
                        dir / "b.vdb"));
    auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(readGrid(dir / "b.vdb", "visibility"));
    REQUIRE(grid);
    return grid;
}

}  // namespace

TEST_CASE("volume: box voxels match a points bake exactly, every baked voxel is active, lit regions are tiles", "[volume]") {
    ScratchDir dir("volume");
    bake(dir, sceneJson({{"type", "volume"}, {"box", {{-6, 0.05, -6}, {6, 1.15, 6}}}, {"voxel_size", 0.1}, {"irradiance", true}},
                        dir / "out/v.vdb"));
    auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(readGrid(dir / "out/v.vdb", "visibility"));
    REQUIRE(grid);
    auto irradiance = openvdb::gridPtrCast<openvdb::Vec3SGrid>(readGrid(dir / "out/v.vdb", "irradiance"));
    REQUIRE(irradiance);
    CHECK(grid->background() == 0.0f);  // outside the box: not baked
    CHECK(grid->getGridClass() == openvdb::GRID_FOG_VOLUME);
    CHECK(irradiance->getGridClass() == openvdb::GRID_UNKNOWN);
    CHECK(grid->voxelSize() == openvdb::Vec3d(0.1));  // exactly as given

    // 120 x 11 x 120 voxels; their centres, in the kind's receiver order, become point receivers.
    const int nx = 120, ny = 11, nz = 120;
    std::vector<float> rows;
    std::vector<openvdb::Coord> coords;
    for (int i = 0; i < nx; ++i)
        for (int j = 0; j < ny; ++j)
            for (int k = 0; k < nz; ++k) {
                openvdb::Vec3d p = grid->indexToWorld(openvdb::Coord(i, j, k));
                rows.insert(rows.end(), {float(p.x()), float(p.y()), float(p.z()), 0, 0, 0});
                coords.emplace_back(i, j, k);
            }
    CHECK(grid->indexToWorld(openvdb::Coord(0, 0, 0)).eq(openvdb::Vec3d(-5.95, 0.1, -5.95), 1e-9));
    uint64_t shape[2] = {coords.size(), 6};
    writeNpy(dir / "points.npy", "<f4", shape, rows.data(), rows.size() * 4);
    bake(dir, sceneJson({{"type", "points"}, {"path", dir / "points.npy"}}, dir / "points-v.npy"));
    NpyArray expected = readNpy(dir / "points-v.npy");
    REQUIRE(expected.shape[0] == coords.size());
    std::vector<float> ev(coords.size());
    std::memcpy(ev.data(), expected.data.data(), ev.size() * 4);

    auto acc = grid->getConstAccessor();
    auto eacc = irradiance->getConstAccessor();
    size_t mismatches = 0, shadowed = 0, inactive = 0;
    for (size_t r = 0; r < coords.size(); ++r) {
        mismatches += acc.getValue(coords[r]) != ev[r];
        shadowed += ev[r] < 1.0f;
        if (!acc.isValueOn(coords[r])) ++inactive;  // lit voxels too are part of the grid
    }
    CHECK(mismatches == 0);
    CHECK(inactive == 0);
    CHECK(shadowed > 100);
    CHECK(acc.getValue(openvdb::Coord(60, 5, 60)) == 0.0f);  // (0.05, 0.6, 0.05): umbra under the blocker
    CHECK(eacc.getValue(openvdb::Coord(0, 5, 0)).x() > 0.0f);  // zero normal: lit voxels still get irradiance

    // Mostly lit: voxels stored densely in leaves are a small part of the box; the active
    // bounds are the box, what Blender's volume object spans.
    const uint64_t total = uint64_t(nx) * ny * nz;
    CHECK(grid->tree().activeVoxelCount() == total);
    CHECK(grid->evalActiveVoxelBoundingBox() == openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(nx - 1, ny - 1, nz - 1)));
    // The lower 8 rows of leaves lie inside the box (the upper ones straddle its top, y = 11,
    // and stay leaves): there, only leaves with shadow are stored densely.
    uint64_t lowerLeaves = 0;
    for (auto leaf = grid->tree().cbeginLeaf(); leaf; ++leaf) lowerLeaves += leaf->origin().y() == 0;
    CHECK(lowerLeaves * 512 < uint64_t(nx) * 8 * nz / 4);
    CHECK(grid->tree().activeTileCount() > 0);

    // The slice tool renders it.
    RunResult slice = runPenumbra("vdb-slice " + (dir / "out/v.vdb") + " " + (dir / "slice.png") + " --axis y --at 0.5");
    INFO(slice.err);
    CHECK(slice.exitCode == 0);
    CHECK(std::filesystem::file_size(dir / "slice.png") > 100);
    RunResult outside = runPenumbra("vdb-slice " + (dir / "out/v.vdb") + " " + (dir / "s.png") + " --axis y --at 7");
    CHECK(outside.exitCode == 1);
    CHECK_THAT(outside.err, Catch::Contains("outside the grid"));

    // The slice never replaces its input, by any name, and reads regular files only.
    std::filesystem::create_symlink(dir / "out/v.vdb", dir / "link.png");
    requireCleanError(runPenumbra("vdb-slice " + (dir / "out/v.vdb") + " " + (dir / "link.png") + " --axis y --at 0.5"), "is also an input");
    CHECK(slurp(dir / "out/v.vdb").compare(0, 4, " BDV") == 0);  // still a VDB (its magic number)
    requireCleanError(runPenumbra("vdb-slice /dev/zero " + (dir / "z.png") + " --axis y --at 0"), "is a character device");
    // A folder typed by hand is not made (it made /nonexistent_dir), and the output is named .png.
    requireCleanError(runPenumbra("vdb-slice " + (dir / "out/v.vdb") + " " + (dir / "typo/deeper/s.png") + " --axis y --at 0.5"),
                      "typo");
    CHECK_FALSE(std::filesystem::exists(dir / "typo"));
    requireCleanError(runPenumbra("vdb-slice " + (dir / "out/v.vdb") + " " + (dir / "s.jpg") + " --axis y --at 0.5"),
                      "s.jpg: vdb-slice writes a PNG: name the output .png");
    // --axis and --at are required, as the synopsis says (without them it sliced along y at 0).
    for (const std::string& missing : {" --axis y", " --at 0.5"}) {
        RunResult usage = runPenumbra("vdb-slice " + (dir / "out/v.vdb") + " " + (dir / "m.png") + missing);
        CHECK(usage.exitCode == 2);
        CHECK_THAT(usage.err, Catch::Contains("is required"));
        CHECK_FALSE(std::filesystem::exists(dir / "m.png"));
    }

    // Cut or damaged copies: one line naming the file, well inside 2 GB of address space (OpenVDB's
    // own reader went on past the end of a cut file and filled strings of gigabytes).
    const std::string whole = slurp(dir / "out/v.vdb");
    for (int part = 1; part < 16; ++part) {
        const std::string damaged = dir / fmt::format("cut{}.vdb", part);
        std::ofstream(damaged, std::ios::binary) << whole.substr(0, whole.size() * size_t(part) / 16);
        RunResult r = runPenumbra("vdb-slice " + damaged + " " + (dir / "cut.png") + " --axis y --at 0.5", "prlimit --as=2000000000");
        INFO(part << ": " << r.err);
        CHECK(r.exitCode == 1);
        CHECK(lineCount(r.err) == 1);
        CHECK(r.err.size() < 400);
        CHECK_THAT(r.err, Catch::StartsWith("penumbra: error: " + damaged + ": "));
        CHECK(!std::filesystem::exists(dir / "cut.png"));
    }
}

TEST_CASE("volume: fully shadowed regions become tiles", "[volume]") {
    ScratchDir dir("volume-umbra");
    // A box entirely under the blocker's umbra (tight around the axis, just below the blocker).
    bake(dir, sceneJson({{"type", "volume"}, {"box", {{-0.4, 0.8, -0.4}, {0.4, 1.12, 0.4}}}, {"voxel_size", 0.01}},
                        dir / "u.vdb"));
    auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(readGrid(dir / "u.vdb", "visibility"));
    REQUIRE(grid);
    auto acc = grid->getConstAccessor();
    CHECK(acc.getValue(openvdb::Coord(40, 16, 40)) == 0.0f);
    CHECK(grid->tree().activeVoxelCount() > 0);
    CHECK(grid->tree().activeTileCount() > 0);  // collapsed 8^3 umbra leaves
}

TEST_CASE("volume: a narrow band holds the voxels near the geometry", "[volume]") {
    ScratchDir dir("volume-band");
    auto grid = bakeBand(dir, 0.15);
    CHECK(grid->indexToWorld(openvdb::Coord(3, 1, -2)).eq(openvdb::Vec3d(0.3, 0.1, -0.2), 1e-12));
    auto acc = grid->getConstAccessor();
    CHECK(acc.getValue(openvdb::Coord(0, 1, 0)) < 1.0f);  // in the band, under the blocker
    // Between floor and blocker: not in the band, the background 0 and inactive.
    CHECK(acc.getValue(openvdb::Coord(0, 5, 0)) == 0.0f);
    CHECK(!acc.isValueOn(openvdb::Coord(0, 5, 0)));
    auto lo = grid->getMetadata<openvdb::Vec3IMetadata>("penumbra_min");
    auto hi = grid->getMetadata<openvdb::Vec3IMetadata>("penumbra_max");
    REQUIRE(lo);
    REQUIRE(hi);
    CHECK(lo->value() == openvdb::Vec3i(-31, -1, -31));
    CHECK(hi->value() == openvdb::Vec3i(31, 16, 31));
}

TEST_CASE("volume: a narrow band of width 0 holds every lattice point on the geometry", "[volume]") {
    // The floor (6 x 6 at y = 0) holds the lattice points (i, 0, k), |i|, |k| <= 30, at voxel_size
    // 0.1; rounding in the distance and in the triangles' lattice boxes left some of them out.
    ScratchDir dir("volume-band-0");
    const auto grid = bakeBand(dir, 0);
    auto acc = grid->getConstAccessor();
    int missing = 0;
    for (int i = -30; i <= 30; ++i)
        for (int k = -30; k <= 30; ++k) missing += !acc.isValueOn(openvdb::Coord(i, 0, k));
    CHECK(missing == 0);
    CHECK(!acc.isValueOn(openvdb::Coord(0, 5, 0)));  // off the geometry
}

TEST_CASE("volume: the narrow band is found in the bake's scan pass: the geometry is opened once", "[volume]") {
    // A geometry type that counts how often it is opened: the pipeline opens the scene once (and
    // rewinds it for the bucket pass); the band no longer reads the source on its own.
    static int opened = 0;
    registerSourceType("counted-floor", [](const SourceRequest& r) {
        ++opened;
        const nlohmann::json params = {{"path", kFloor}};
        return openSource("glb", SourceRequest{params, r.file, r.path, r.baseDir});
    });
    ScratchDir dir("volume-band-once");
    nlohmann::json scene =
        sceneJson({{"type", "volume"}, {"narrow_band", {{"geometry", {0}}, {"width", 0.15}}}, {"voxel_size", 0.1}}, dir / "c.vdb");
    scene["geometry"][0] = {{"type", "counted-floor"}};
    opened = 0;
    bake(dir, scene);
    CHECK(opened == 1);
    // The same voxels as the band read from the file itself.
    bake(dir, sceneJson({{"type", "volume"}, {"narrow_band", {{"geometry", {0}}, {"width", 0.15}}}, {"voxel_size", 0.1}},
                        dir / "b.vdb"));
    auto counted = openvdb::gridPtrCast<openvdb::FloatGrid>(readGrid(dir / "c.vdb", "visibility"));
    auto direct = openvdb::gridPtrCast<openvdb::FloatGrid>(readGrid(dir / "b.vdb", "visibility"));
    REQUIRE(counted);
    REQUIRE(direct);
    CHECK(counted->activeVoxelCount() == direct->activeVoxelCount());
    CHECK(counted->tree().hasSameTopology(direct->tree()));
}

TEST_CASE("volume: bad parameters are one-line errors naming the key", "[volume]") {
    ScratchDir dir("volume-errors");
    auto error = [&](const nlohmann::json& receivers, const std::string& output = "v.vdb") {
        AllowOutsidePaths examples;
        return errorOf([&] { parseScene(sceneJson(receivers, output), dir / "scene.json"); });
    };
    const nlohmann::json box = {{-1, 0, -1}, {1, 1, 1}};
    CHECK_THAT(error({{"type", "volume"}, {"box", box}}), Catch::Contains("receivers.voxel_size"));
    CHECK_THAT(error({{"type", "volume"}, {"box", box}, {"voxel_size", 0}}), Catch::Contains("receivers.voxel_size"));
    CHECK_THAT(error({{"type", "volume"}, {"voxel_size", 0.1}}), Catch::Contains("receivers.box"));
    CHECK_THAT(error({{"type", "volume"}, {"box", {{1, 0, 0}, {0, 1, 1}}}, {"voxel_size", 0.1}}),
               Catch::Contains("receivers.box") && Catch::Contains("low"));
    CHECK_THAT(error({{"type", "volume"}, {"box", {1, 2}}, {"voxel_size", 0.1}}), Catch::Contains("receivers.box"));
    CHECK_THAT(error({{"type", "volume"}, {"box", box}, {"voxel_size", 0.1}}, "v.exr"), Catch::Contains("output"));
    CHECK_THAT(error({{"type", "volume"}, {"box", box}, {"voxel_size", 1e-6}}), Catch::Contains("voxels"));
    // Voxel centres past the float range were blamed on a receiver_offset the scene did not have.
    CHECK_THAT(error({{"type", "volume"}, {"box", box}, {"voxel_size", 1e300}}),
               Catch::Contains("receivers.voxel_size: voxel centres would lie at 5e+299 along x, beyond the float range"));
    CHECK_THAT(error({{"type", "volume"}, {"box", {{1e39, 0, 0}, {1e39, 1, 1}}}, {"voxel_size", 0.5}}),
               Catch::Contains("receivers.box: voxel centres would lie at 1e+39 along x"));
    CHECK_THAT(error({{"type", "volume"}, {"box", {{0, 0, 0}, {1e300, 1, 1}}}, {"voxel_size", 0.1}}),
               Catch::Contains("the box would have 1e+303 voxels"));
    CHECK_THAT(error({{"type", "volume"}, {"voxel_size", 0.1}, {"narrow_band", {{"geometry", {2}}, {"width", 0.1}}}}),
               Catch::Contains("receivers.narrow_band.geometry[0]") && Catch::Contains("out of range"));
    CHECK_THAT(error({{"type", "volume"}, {"voxel_size", 0.1}, {"narrow_band", {{"geometry", {0}}}}}),
               Catch::Contains("receivers.narrow_band.width"));
    // Any list of geometry entries (a band's, a lightmap's or a vertex bake's meshes) names each once.
    CHECK_THAT(error({{"type", "volume"}, {"voxel_size", 0.1}, {"narrow_band", {{"geometry", {0, 0}}, {"width", 0.1}}}}),
               Catch::Contains("receivers.narrow_band.geometry[1]: geometry 0 is listed twice"));
    CHECK_THAT(error({{"type", "vertices"}, {"meshes", {0, 0}}}, "v.glb"), Catch::Contains("receivers.meshes[1]: geometry 0 is listed twice"));
    CHECK_THAT(error({{"type", "volume"}, {"voxel_size", 0.1}, {"narrow_band", {{"geometry", {0}}, {"width", 1}, {"x", 1}}}}),
               Catch::Contains("receivers.narrow_band.x"));
}

TEST_CASE("volume: the example bakes with one command", "[volume]") {
    ScratchDir dir("volume-example");
    RunResult r = runPenumbra("bake " + std::string(PENUMBRA_SOURCE_DIR) + "/examples/volume.json --quiet -o " + (dir / "v.vdb"));
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(readGrid(dir / "v.vdb", "visibility"));
    REQUIRE(grid);
    CHECK(grid->tree().activeVoxelCount() > 0);
}

TEST_CASE("volume: the same grids are the same bytes, on 1 and 2 threads and from run to run", "[volume][cli]") {
    // OpenVDB writes a random UUID into every file's header; the bake replaces it with one made
    // from the rest of the file (stampContentUuid), so the determinism rule holds for VDBs too.
    ScratchDir dir("volume-bytes");
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/examples/volume.json";
    for (const std::string& run : {"t1", "t2", "t2-again"}) {
        RunResult r = runPenumbra("bake " + scene + " --quiet --threads " + (run == "t1" ? "1" : "2") + " -o " + (dir / (run + ".vdb")));
        INFO(r.err);
        REQUIRE(r.exitCode == 0);
    }
    const std::string t1 = slurp(dir / "t1.vdb");
    CHECK(t1 == slurp(dir / "t2.vdb"));
    CHECK(t1 == slurp(dir / "t2-again.vdb"));
    REQUIRE(t1.size() > 57);
    const std::string uuid = t1.substr(21, 36);
    INFO(uuid);
    CHECK(uuid[8] == '-');
    CHECK(uuid[14] == '8');  // version 8: made by penumbra, not random
    CHECK(std::string("89ab").find(uuid[19]) != std::string::npos);
    // Still a file OpenVDB reads, and another scene gets another UUID.
    auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(readGrid(dir / "t1.vdb", "visibility"));
    REQUIRE(grid);
    RunResult other = runPenumbra("bake " + scene + " --quiet --penumbra-map-bias 1 --method penumbra-map -o " + (dir / "pm.vdb"));
    REQUIRE(other.exitCode == 0);
    CHECK(slurp(dir / "pm.vdb").substr(21, 36) != uuid);
}

TEST_CASE("volume: pyopenvdb reads the grid class, the exact voxel size and the baked box as bounds", "[volume]") {
    // Debian's python3-openvdb is a module of the system Python (setup.sh installs it).
    if (runShell("/usr/bin/python3 -c 'import pyopenvdb' >/dev/null 2>&1") != 0) {
        WARN("skipped: /usr/bin/python3 cannot import pyopenvdb (Debian package python3-openvdb)");
        return;
    }
    ScratchDir dir("volume-pyopenvdb");
    bake(dir, sceneJson({{"type", "volume"}, {"box", {{-1, 0.05, -1}, {1, 1.15, 1}}}, {"voxel_size", 0.05}, {"irradiance", true}},
                        dir / "v.vdb"));
    const std::string script = dir / "read.py";
    std::ofstream(script) << "import pyopenvdb as vdb, sys\n"
                             "grids, meta = vdb.readAll(sys.argv[1])\n"
                             "for g in sorted(grids, key=lambda g: g.name):\n"
                             "    lo, hi = g.evalActiveVoxelBoundingBox()\n"
                             "    print(g.name, g.gridClass, repr(g.transform.voxelSize()[0]), g.background, lo, hi, g.activeVoxelCount())\n";
    const int code = runShell("/usr/bin/python3 " + script + " " + (dir / "v.vdb") + " >" + (dir / "out.txt") + " 2>&1");
    const std::string out = slurp(dir / "out.txt");
    INFO(out);
    REQUIRE(code == 0);
    // 40 x 22 x 40 voxels of 0.05 in the box, every one active: the bounds are the box.
    CHECK_THAT(out, Catch::Contains("irradiance unknown 0.05 (0.0, 0.0, 0.0) (0, 0, 0) (39, 21, 39) 35200"));
    CHECK_THAT(out, Catch::Contains("visibility fog volume 0.05 0.0 (0, 0, 0) (39, 21, 39) 35200"));
}

