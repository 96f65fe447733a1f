// A real full disk, not a file-size limit: a small tmpfs mounted in the test's own directory
// (or, where tmpfs cannot be mounted, a loop-mounted ext2 image; where neither can, the cases
// are skipped with a notice saying why). Bucket files and every output hit ENOSPC in turn: each
// time one line names the file, the exit code is 1, no temporary is left and no earlier output
// is clobbered. Both with O_TMPFILE and with the named fallback (PENUMBRA_NO_TMPFILE).

#include "CliRunner.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <sys/mount.h>
#include <sys/statvfs.h>

#include <set>

using namespace penumbra::test;
namespace fs = std::filesystem;

namespace {

/// A file system of @p bytes mounted at DIR/disk for the fixture's lifetime.
class SmallDisk {
public:
    explicit SmallDisk(uint64_t bytes) : dir_("full-disk"), mountPoint_(dir_ / "disk") {
        fs::create_directory(mountPoint_);
        const std::string options = "size=" + std::to_string(bytes);
        if (::mount("tmpfs", mountPoint_.c_str(), "tmpfs", 0, options.c_str()) == 0) {
            mounted_ = true;
            return;
        }
        why_ = std::string("mount -t tmpfs: ") + std::strerror(errno);
        // A loop-mounted ext2 image of the same size (needs mkfs.ext2 and loop devices).
        const std::string image = dir_ / "disk.img";
        const std::string make = "truncate -s " + std::to_string(bytes) + " " + image + " && mkfs.ext2 -q -F -m 0 " + image +
                                 " >/dev/null 2>&1 && mount -o loop " + image + " " + mountPoint_ + " 2>/dev/null";
        if (std::system(make.c_str()) == 0) {
            mounted_ = true;
            return;
        }
        why_ += "; loop-mounted ext2: mkfs.ext2 or mount -o loop failed";
    }
    ~SmallDisk() {
        if (mounted_) ::umount2(mountPoint_.c_str(), MNT_DETACH);
    }
    SmallDisk(const SmallDisk&) = delete;
    SmallDisk& operator=(const SmallDisk&) = delete;

    bool mounted() const { return mounted_; }
    const std::string& whyNot() const { return why_; }
    std::string operator/(const std::string& name) const { return mountPoint_ + "/" + name; }
    const std::string& path() const { return mountPoint_; }
    const ScratchDir& scratch() const { return dir_; }
    uint64_t freeBytes() const {
        struct statvfs s {};
        return ::statvfs(mountPoint_.c_str(), &s) == 0 ? uint64_t(s.f_bavail) * s.f_frsize : 0;
    }
    /// Fills the disk until only about @p keep bytes are free.
    void fillLeaving(uint64_t keep) const {
        const uint64_t free = freeBytes();
        if (free <= keep) return;
        std::ofstream(mountPoint_ + "/filler", std::ios::binary | std::ios::app) << std::string(size_t(free - keep), 'f');
    }

private:
    ScratchDir dir_;
    std::string mountPoint_;
    bool mounted_ = false;
    std::string why_;
};

nlohmann::json grassScene(uint64_t blades, const std::string& output) {
    return {{"geometry", listOf({{"type", "grass"}, {"count", blades}, {"area", {{-2, -2}, {2, 2}}}, {"segments", 5}, {"seed", 3}})},
            {"lights", listOf({{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}, {"samples", 16}, {"sample_sets", 2}})},
            {"receivers", {{"type", "camera"}, {"eye", {0, 3, 3}}, {"target", {0, 0, 0}}, {"width", 64}, {"height", 48}}},
            {"output", output}};
}

std::vector<std::string> namesIn(const std::string& dir) {
    std::vector<std::string> names;
    for (const auto& e : fs::recursive_directory_iterator(dir)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

#define REQUIRE_DISK(disk)                                                             \
    if (!(disk).mounted()) {                                                           \
        WARN("skipped: no small file system could be mounted (" << (disk).whyNot() << ")"); \
        return;                                                                        \
    }

}  // namespace

TEST_CASE("full disk: bucket files that cannot fit are refused before any work", "[cli][full-disk]") {
    SmallDisk disk(8 << 20);
    REQUIRE_DISK(disk);
    const std::string scene = disk.scratch() / "scene.json";
    std::ofstream(scene) << grassScene(300000, "out/x.exr").dump();
    // Without cull before spill, 40 bytes per triangle is what the bucket pass writes.
    RunResult r = runPenumbra("bake " + scene + " --disable cull-before-spill --tmp " + disk.path());
    requireCleanError(r, "--tmp " + disk.path() + ": the bucket files of 1500000 triangles need 57.2 MiB, but it has 8.00 MiB free");
    CHECK(r.err.find("[scan]") == std::string::npos);  // refused before the first triangle
    CHECK(namesIn(disk.path()).empty());
}

TEST_CASE("full disk: blockers out of every light's reach need no room, with cull before spill", "[cli][full-disk]") {
    // The check counted every triangle, also those the cull never writes: a million blades out of
    // reach were refused on a disk they would not have touched.
    SmallDisk disk(8 << 20);
    REQUIRE_DISK(disk);
    const std::string scene = disk.scratch() / "scene.json";
    nlohmann::json s = grassScene(60000, "out/x.exr");  // 300,000 triangles: 11.5 MiB of bucket records at most
    s["geometry"][0]["area"] = {{40, 40}, {44, 44}};
    s["geometry"].push_back({{"type", "grass"}, {"count", 200}, {"area", {{-1, -1}, {1, 1}}}});
    std::ofstream(scene) << s.dump();
    RunResult r = runPenumbra("bake " + scene + " -q --tmp " + disk.path() + " --stats " + (disk.scratch() / "stats.json"));
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.err, Catch::Contains("need up to 11.5 MiB, less what cull before spill drops"));
    CHECK(lineCount(r.err) == 1);
    const nlohmann::json stats = nlohmann::json::parse(slurp(disk.scratch() / "stats.json"));
    CHECK(stats["buckets"]["bytes_written"].get<uint64_t>() < (1u << 20));
    CHECK(namesIn(disk.path()).empty());
}

TEST_CASE("full disk: bucket files hitting ENOSPC name the directory and leave nothing", "[cli][full-disk]") {
    for (bool named : {false, true}) {
        SmallDisk disk(8 << 20);
        REQUIRE_DISK(disk);
        // The plan counts 40 bytes per triangle; the files also round up to whole pages, so a
        // stream that just fits the plan overflows the disk while it is written.
        const uint64_t blades = (disk.freeBytes() - 8192) / 40 / 5;
        const std::string scene = disk.scratch() / "scene.json";
        std::ofstream(scene) << grassScene(blades, "out/x.exr").dump();
        // Every triangle is spilled: culling before the spill would keep the files under the plan.
        RunResult r = runPenumbra("bake " + scene + " -q --disable cull-before-spill --tmp " + disk.path(),
                                  named ? "PENUMBRA_NO_TMPFILE=1" : "");
        INFO((named ? "named temporaries: " : "O_TMPFILE: ") << r.err);
        requireCleanError(r, "No space left on device");
        CHECK_THAT(r.err, Catch::Contains(disk.path() + "/penumbra-buckets-") && Catch::Contains("cannot write bucket"));
        CHECK(namesIn(disk.path()).empty());
        CHECK_FALSE(fs::exists(disk.scratch() / "out/x.exr"));
    }
}

TEST_CASE("full disk: every output hitting ENOSPC in turn leaves the earlier outputs whole", "[cli][full-disk]") {
    for (bool named : {false, true}) {
        SmallDisk disk(4 << 20);
        REQUIRE_DISK(disk);
        const std::string scene = disk.scratch() / "scene.json";
        std::ofstream(scene) << grassScene(200, disk / "out/x.exr").dump();
        fs::create_directories(disk / "out");
        fs::create_directories(disk / "dump");
        for (const char* name : {"out/x.exr", "out/x.png", "stats.json", "dump/masks.npy"})
            std::ofstream(disk / name) << "previous " << name;
        const std::string bake = "bake " + scene + " -q --allow-outside-uris --stats " + (disk / "stats.json") + " --dump " +
                                 (disk / "dump");
        // From almost no room up to enough: each attempt fails cleanly on the first output that
        // does not fit, or succeeds with every output complete.
        bool succeeded = false;
        std::set<std::string> failedOn;
        for (uint64_t keep = 4096; !succeeded && keep < (2u << 20); keep *= 2) {
            fs::remove(disk / "filler");
            disk.fillLeaving(keep);
            RunResult r = runPenumbra(bake, named ? "PENUMBRA_NO_TMPFILE=1" : "");
            INFO((named ? "named temporaries, " : "O_TMPFILE, ") << keep << " bytes free: " << r.err);
            CHECK_FALSE(hasTempFiles(disk.path()));
            if (r.exitCode == 0) {
                succeeded = true;
                CHECK(slurp(disk / "out/x.exr").rfind("previous", 0) != 0);
                CHECK(nlohmann::json::parse(slurp(disk / "stats.json"))["receivers"].get<uint64_t>() > 0);
                break;
            }
            // The library writing an EXR words ENOSPC its own way; the file is named either way.
            requireCleanError(r, disk.path());
            CHECK(namesIn(disk.path()) ==
                  (std::vector<std::string>{"dump", "filler", "masks.npy", "out", "stats.json", "x.exr", "x.png"}));
            for (const char* name : {"out/x.exr", "out/x.png", "stats.json", "dump/masks.npy"})
                CHECK(slurp(disk / name) == std::string("previous ") + name);
            failedOn.insert(r.err.substr(0, r.err.find(':', 17)));
        }
        CHECK(succeeded);
        CHECK(failedOn.size() >= 2);  // more than one output had its turn
    }
}

TEST_CASE("full disk: a dump directory the bake made is gone when the dump does not fit", "[cli][full-disk]") {
    // Outputs appear whole or not at all: the files were never linked, but the directory made
    // for them stayed, empty. One that existed before stays.
    SmallDisk disk(1 << 20);
    REQUIRE_DISK(disk);
    const std::string scene = disk.scratch() / "scene.json";
    std::ofstream(scene) << grassScene(200, disk.scratch() / "x.exr").dump();
    disk.fillLeaving(4096);
    for (bool existed : {false, true}) {
        if (existed) fs::create_directories(disk / "dump");
        RunResult r = runPenumbra("bake " + scene + " -q --allow-outside-uris --dump " + (disk / "dump"));
        INFO(r.err);
        requireCleanError(r, disk.path());
        CHECK(fs::exists(disk / "dump") == existed);
        if (existed) CHECK(fs::is_empty(disk / "dump"));
        CHECK_FALSE(hasTempFiles(disk.path()));
    }
}

TEST_CASE("full disk: a .vdb that does not fit is refused, and the previous one stays", "[cli][full-disk][volume]") {
    // io::File writes through a stream it never checks: a full disk left a truncated .vdb, exit 0.
    SmallDisk disk(1 << 20);
    REQUIRE_DISK(disk);
    nlohmann::json scene = grassScene(200, disk / "v.vdb");
    scene["receivers"] = {{"type", "volume"}, {"box", {{-2, 0.05, -2}, {2, 0.5, 2}}}, {"voxel_size", 0.05}};
    const std::string path = disk.scratch() / "scene.json";
    std::ofstream(path) << scene.dump();
    std::ofstream(disk / "v.vdb") << "previous";
    bool succeeded = false;
    for (uint64_t keep = 4096; !succeeded && keep < (1u << 20); keep *= 2) {
        fs::remove(disk / "filler");
        disk.fillLeaving(keep);
        const RunResult r = runPenumbra("bake " + path + " -q --allow-outside-uris");
        INFO(keep << " bytes free: " << r.err);
        CHECK_FALSE(hasTempFiles(disk.path()));
        if (r.exitCode == 0) {
            succeeded = true;
            CHECK(runPenumbra("vdb-slice " + (disk / "v.vdb") + " " + (disk.scratch() / "s.png") + " --axis y --at 0.25").exitCode == 0);
            break;
        }
        requireCleanError(r, disk / "v.vdb");
        CHECK(r.err.find("No space left on device") != std::string::npos);
        CHECK(slurp(disk / "v.vdb") == "previous");
    }
    CHECK(succeeded);
}
