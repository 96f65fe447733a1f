#include "bake/WorkPlan.h"

#include "bake/MemoryPlan.h"
#include "bucket/BucketOptions.h"
#include "stream/util/Error.h"
#include "stream/util/Memory.h"
#include "stream/util/Progress.h"

#include <sys/statvfs.h>
#include <sys/sysinfo.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

namespace penumbra {
namespace {
constexpr uint64_t kReadAheadReserve = 16ull << 20;
}  // namespace
namespace {

/// The cgroup v2 memory limit of this process, if it has one.
std::optional<uint64_t> cgroupMemoryLimit() {
    std::ifstream cgroup("/proc/self/cgroup");
    std::string line, path;
    while (std::getline(cgroup, line))
        if (line.rfind("0::", 0) == 0) path = line.substr(3);
    if (path.empty()) return std::nullopt;
    std::ifstream max("/sys/fs/cgroup" + path + "/memory.max");
    std::string value;
    if (!(max >> value) || value == "max") return std::nullopt;
    try {
        return std::stoull(value);
    } catch (const std::exception&) {
        return std::nullopt;
    }
}

}  // namespace

uint64_t machineMemoryBytes() {
    struct sysinfo info {};
    if (::sysinfo(&info) != 0) return 0;
    uint64_t bytes = (uint64_t(info.totalram) + uint64_t(info.totalswap)) * info.mem_unit;
    if (std::optional<uint64_t> limit = cgroupMemoryLimit()) bytes = std::min(bytes, *limit);
    return bytes;
}

uint64_t freeDiskBytes(const std::string& dir) {
    struct statvfs fs {};
    if (::statvfs(dir.c_str(), &fs) != 0) return 0;
    return uint64_t(fs.f_bavail) * fs.f_frsize;
}

uint64_t addressSpaceNeeded(uint64_t neededBytes) { return mappedBytes() + neededBytes + kReadAheadReserve; }

void checkAddressSpaceLeft(const std::string& scene, const char* what, uint64_t neededBytes, uint64_t wholeBake) {
    // The plan's estimate of what is already mapped can be short: ask the kernel. The read-ahead
    // thread's stack rides along.
    const uint64_t limit = addressSpaceLimit();
    if (!limit || addressSpaceAvailable(neededBytes + kReadAheadReserve)) return;
    const uint64_t phase = addressSpaceNeeded(neededBytes);
    if (wholeBake <= phase)
        fail(scene, "{} does not fit under the address-space limit (prlimit --as, ulimit -v) of {}: at least {} is needed", what,
             formatBytes(limit), budgetText(phase));
    // The rest of the bake at its worst (every receiver the scan may find) is what the limit named
    // must hold, so that it is not refused again; less may do, and the user is told so.
    fail(scene, "{} does not fit under the address-space limit (prlimit --as, ulimit -v) of {}: at least {} is sure to "
                "do for the whole bake at its worst (the pass itself needs {})",
         what, formatBytes(limit), budgetText(wholeBake), budgetText(phase));
}

void checkMemoryFits(const std::string& scene, const char* what, uint64_t neededBytes) {
    const uint64_t machine = machineMemoryBytes();
    if (machine == 0 || neededBytes <= machine) return;
    fail(scene, "{} needs at least {} of memory, but this machine has {} (physical memory and swap); make the "
                "receivers fewer (a smaller image, lightmap or volume)",
         what, formatBytes(neededBytes), formatBytes(machine));
}

void checkBucketDisk(const std::string& tmpDir, std::optional<uint64_t> triangles, bool sort, bool mayCull) {
    if (!sort || !triangles) return;
    std::string dir = tmpDir;
    if (dir.empty()) {
        std::error_code ec;
        dir = std::filesystem::temp_directory_path(ec).string();
        if (ec) return;  // the bucket writer reports it
    }
    const uint64_t free = freeDiskBytes(dir);
    const double needed = double(*triangles) * double(kBucketRecordBytes);
    if (free == 0 || needed <= double(free)) return;
    const std::string neededText = needed >= 1.8e19 ? std::string("more than 16 EiB") : formatBytes(uint64_t(needed));
    if (mayCull) {  // a scene whose blockers mostly lie out of reach writes a fraction of this
        printWarning("--tmp {}: the bucket files of {} triangles need up to {}, less what cull before spill drops, and it has "
                     "{} free; the bake stops cleanly if the disk fills",
                     dir, *triangles, neededText, formatBytes(free));
        return;
    }
    fail("--tmp " + dir, "the bucket files of {} triangles need {}, but it has {} free (give --tmp on a larger disk, or "
                         "stream fewer triangles)",
         *triangles, neededText, formatBytes(free));
}

double estimatedSeconds(uint64_t triangles, int tiles, int threads) {
    return double(triangles) * double(2 + std::max(tiles, 1)) * kSecondsPerTrianglePass / double(std::max(threads, 1));
}

void noteLongBake(uint64_t triangles, uint64_t receivers, uint64_t samples, int tiles, int threads, bool quiet) {
    const double streaming = estimatedSeconds(triangles, tiles, threads);
    const double shading = double(receivers) * double(samples) * kSecondsPerReceiverSample / double(std::max(threads, 1));
    if (quiet || std::max(streaming, shading) < 3600) return;
    if (streaming >= shading)
        printNote("this bake streams {} triangles {} times; expect about {} on {} thread{} (the plan's estimate)", triangles,
                  2 + std::max(tiles, 1), formatDuration(streaming), threads, threads == 1 ? "" : "s");
    else
        printNote("this bake has up to {} receivers under {} light samples; expect at least {} on {} thread{} (the plan's "
                  "estimate)", receivers, samples, formatDuration(shading), threads, threads == 1 ? "" : "s");
}

}  // namespace penumbra
