#include "stream/util/AnonymousFile.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <mutex>

#include <fcntl.h>
#include <unistd.h>

namespace penumbra {
namespace {

std::mutex scratchMutex;
std::string scratch;

}  // namespace

int createAnonymousFile(const std::string& dir) {
    int fd = -1;
    if (!anonymousFilesDisabled()) {  // PENUMBRA_NO_TMPFILE forces the fallback, for its tests
        fd = ::open(dir.c_str(), O_RDWR | O_TMPFILE | O_CLOEXEC, 0600);
        if (fd >= 0) return fd;
        // EISDIR / EOPNOTSUPP / EINVAL: no O_TMPFILE here (old kernel, some network file systems).
        if (errno != EISDIR && errno != EOPNOTSUPP && errno != EINVAL) return -1;
    }
    static std::atomic<uint64_t> counter{0};
    std::string path = dir + "/penumbra-anonymous-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
    registerTempFile(path);
    fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    int err = errno;
    ::unlink(path.c_str());
    unregisterTempFile(path);
    errno = err;
    return fd;
}

std::string scratchDirectory() {
    {
        std::lock_guard<std::mutex> lock(scratchMutex);
        if (!scratch.empty()) return scratch;
    }
    return systemTempDirectory();
}

std::string systemTempDirectory() {
    const char* env = std::getenv("TMPDIR");
    if (!env || !*env) return "/tmp";
    std::error_code ec;
    const std::string dir = std::filesystem::temp_directory_path(ec).string();
    if (ec) fail(fmt::format("$TMPDIR ({})", env), "cannot use it as the temporary directory: {}", ec.message());
    return dir;
}

void setScratchDirectory(const std::string& dir) {
    std::lock_guard<std::mutex> lock(scratchMutex);
    scratch = dir;
}

}  // namespace penumbra
