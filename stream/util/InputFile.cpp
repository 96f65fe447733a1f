#include "stream/util/InputFile.h"

#include "stream/util/Error.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <map>
#include <mutex>
#include <vector>
#include <system_error>
#include <utility>

namespace penumbra {
namespace {


std::mutex inputsMutex;
int g_scopes = 0;  // guarded by inputsMutex
std::map<std::pair<dev_t, ino_t>, std::string>& inputs() {
    static std::map<std::pair<dev_t, ino_t>, std::string> recorded;
    return recorded;
}

void record(const struct stat& st, const std::string& path) {
    std::lock_guard lock(inputsMutex);
    if (g_scopes > 0) inputs().emplace(std::pair(st.st_dev, st.st_ino), path);
}

void requireRegular(const struct stat& st, const std::string& path) {
    if (!S_ISREG(st.st_mode)) fail(path, "is {}, not a regular file", fileKindName(st.st_mode));
}

}  // namespace

namespace {
FileStamp stampOf(const struct stat& st) {
    return {st.st_dev, st.st_ino, int64_t(st.st_size), int64_t(st.st_mtim.tv_sec), int64_t(st.st_mtim.tv_nsec)};
}
}  // namespace

FileStamp FileStamp::of(const std::string& path) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) fail(path, "cannot stat: {}", errnoText(errno));
    return stampOf(st);
}

FileStamp FileStamp::of(int fd, const std::string& path) {
    struct stat st {};
    if (::fstat(fd, &st) != 0) fail(path, "cannot stat: {}", errnoText(errno));
    return stampOf(st);
}

void requireUnchangedFile(const std::string& path, const FileStamp& first) {
    const FileStamp now = FileStamp::of(path);
    if (now == first) return;
    const std::string how = now.device != first.device || now.inode != first.inode ? std::string("replaced by another file")
                            : now.size != first.size ? fmt::format("rewritten ({} bytes, then {})", first.size, now.size)
                                                     : std::string("rewritten in place (its modification time moved)");
    fail(path, "file changed while it was being read: {} after an earlier pass of this run had read it", how);
}

const char* fileKindName(mode_t mode) {
    if (S_ISREG(mode)) return "a regular file";
    if (S_ISDIR(mode)) return "a directory";
    if (S_ISFIFO(mode)) return "a FIFO";
    if (S_ISCHR(mode)) return "a character device";
    if (S_ISBLK(mode)) return "a block device";
    if (S_ISSOCK(mode)) return "a socket";
    if (S_ISLNK(mode)) return "a symbolic link";
    return "a special file";
}

int openInputFile(const std::string& path) {
    if (path.empty()) throw InputError("cannot open an input: the path is empty");
    // stat() first, so that a device is refused without being opened at all (opening some has
    // side effects); the descriptor is checked again below, as the name may change in between.
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) fail(path, "cannot open: {}", errnoText(errno));
    requireRegular(st, path);
    int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) fail(path, "cannot open: {}", errnoText(errno));
    if (::fstat(fd, &st) != 0) {
        int err = errno;
        ::close(fd);
        fail(path, "cannot stat: {}", errnoText(err));
    }
    if (!S_ISREG(st.st_mode)) {
        ::close(fd);
        requireRegular(st, path);
    }
    int flags = ::fcntl(fd, F_GETFL);
    if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
    record(st, path);
    return fd;
}

std::FILE* openInputStream(const std::string& path) {
    int fd = openInputFile(path);
    std::FILE* file = ::fdopen(fd, "rb");
    if (!file) {
        int err = errno;
        ::close(fd);
        fail(path, "cannot open: {}", errnoText(err));
    }
    return file;
}

void checkInputFile(const std::string& path) { ::close(openInputFile(path)); }

void recordReferencedFile(const std::string& path) {
    struct stat st {};
    if (!path.empty() && ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode)) record(st, path);
}

std::optional<std::string> recordedInput(dev_t device, ino_t inode) {
    std::lock_guard lock(inputsMutex);
    auto it = inputs().find(std::pair(device, inode));
    if (it == inputs().end()) return std::nullopt;
    return it->second;
}

uint64_t recordedInputsFingerprint() {
    std::vector<std::array<int64_t, 3>> files;
    {
        std::lock_guard lock(inputsMutex);
        for (const auto& [id, path] : inputs()) {
            struct stat st {};
            if (::stat(path.c_str(), &st) != 0) continue;  // gone: whoever needs it says so
            files.push_back({int64_t(st.st_size), int64_t(st.st_mtim.tv_sec), int64_t(st.st_mtim.tv_nsec)});
        }
    }
    std::sort(files.begin(), files.end());
    uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a 64
    for (const auto& f : files)
        for (int64_t v : f)
            for (int b = 0; b < 8; ++b) h = (h ^ uint8_t(uint64_t(v) >> (8 * b))) * 0x100000001b3ull;
    return h;
}

InputScope::InputScope() {
    std::lock_guard lock(inputsMutex);
    ++g_scopes;
}

InputScope::~InputScope() {
    std::lock_guard lock(inputsMutex);
    if (--g_scopes == 0) inputs().clear();
}

}  // namespace penumbra
