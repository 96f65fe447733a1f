#include "stream/util/AtomicFile.h"
#include "stream/util/PathText.h"

#include "stream/util/Error.h"
#include "stream/util/InputFile.h"

#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <system_error>
#include <utility>

namespace penumbra {

/// A file whose bytes are all written, waiting to be put in place. Owns its descriptor and
/// any name it has; destroying it discards the file.
struct AtomicFile::Finished {
    std::string finalPath, targetPath;
    Target target = Target::Regular;
    int fd = -1;
    std::string tempName;  ///< the named temporary (fallback), if any
    std::string staged;    ///< a registered link name while an OutputSet commits
    bool sync = false;     ///< fsync the directory once the file has its name (syncOnCommit)

    Finished() = default;
    Finished(const Finished&) = delete;
    Finished& operator=(const Finished&) = delete;
    ~Finished() {
        if (fd >= 0) ::close(fd);
        for (std::string* name : {&tempName, &staged})
            if (!name->empty()) {
                ::unlink(name->c_str());
                unregisterTempFile(*name);
            }
    }
};

namespace {

/// Write-behind buffer size. Big enough that syscall overhead is irrelevant for multi-GB
/// outputs, small enough not to matter for the memory budget.
constexpr size_t kBufferBytes = 256 * 1024;


std::mutex g_setMutex;
OutputSet* g_openSet = nullptr;

/// Removes the temporaries "BASE.tmp-<pid>-<n>" of processes that no longer run. A SIGKILL (or a
/// power cut) between linking a staged name and renaming it over the old file, or while a named
/// temporary is written, leaves one behind, since nothing can run then; the next write of the
/// same file clears it. A live pid, this process's or another's (another bake writing the same
/// file now, or an unrelated process that reuses the pid), keeps its files.
void removeStaleTemporaries(const std::string& base) {
    const std::filesystem::path path(base);
    const std::string prefix = path.filename().string() + ".tmp-";
    std::error_code ec;
    for (const auto& entry : std::filesystem::directory_iterator(path.parent_path().empty() ? "." : path.parent_path(), ec)) {
        const std::string name = entry.path().filename().string();
        if (name.compare(0, prefix.size(), prefix) != 0) continue;
        char* end = nullptr;
        const long pid = std::strtol(name.c_str() + prefix.size(), &end, 10);
        const std::string_view counter = end && *end == '-' ? std::string_view(end + 1) : std::string_view();
        const auto digit = [](char c) { return c >= '0' && c <= '9'; };
        if (pid <= 0 || counter.empty() || !std::all_of(counter.begin(), counter.end(), digit)) continue;
        if (::kill(pid_t(pid), 0) != 0 && errno == ESRCH) {
            std::error_code ignored;
            std::filesystem::remove(entry.path(), ignored);
        }
    }
}

/// "BASE.tmp-<pid>-<n>": the pid keeps processes apart, the counter the files of one process.
/// Stale ones of dead processes are removed first (removeStaleTemporaries).
std::string uniqueName(const std::string& base) {
    static std::atomic<uint64_t> counter{0};
    removeStaleTemporaries(base);
    return fmt::format("{}.tmp-{}-{}", base, static_cast<long>(::getpid()), counter.fetch_add(1));
}

/// Anonymous files are reopened (by libraries) and linked through /proc/self/fd.
bool procFdWorks() {
    static const bool works = ::access("/proc/self/fd", X_OK) == 0;
    return works;
}

std::string procPath(int fd) { return "/proc/self/fd/" + std::to_string(fd); }

/// Blocks the termination signals that have handlers on this thread while it lives, so that a
/// handler does not run between linking a temporary name and renaming it.
class SignalsHeld {
public:
    SignalsHeld() {
        sigset_t set;
        sigemptyset(&set);
        for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) sigaddset(&set, sig);
        ::pthread_sigmask(SIG_BLOCK, &set, &old_);
    }
    ~SignalsHeld() { ::pthread_sigmask(SIG_SETMASK, &old_, nullptr); }

private:
    sigset_t old_;
};

/// Links the anonymous file @p fd as @p name; 0 or the errno.
int linkAnonymous(int fd, const std::string& name) {
    return ::linkat(AT_FDCWD, procPath(fd).c_str(), AT_FDCWD, name.c_str(), AT_SYMLINK_FOLLOW) == 0 ? 0 : errno;
}

/// Links @p f's anonymous file under a fresh, registered name beside its target.
void stage(AtomicFile::Finished& f) {
    for (int attempt = 0;; ++attempt) {
        std::string name = uniqueName(f.targetPath);
        registerTempFile(name);
        const int err = linkAnonymous(f.fd, name);
        if (err == 0) {
            f.staged = std::move(name);
            return;
        }
        unregisterTempFile(name);
        if (err != EEXIST || attempt >= 1000) fail(f.finalPath, "cannot create file: {}", errnoText(err));
    }
}

/// Renames @p from over @p f's target, refusing to replace anything but a regular file.
void renameOver(AtomicFile::Finished& f, std::string& from) {
    struct stat st {};
    if (::lstat(f.targetPath.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
        fail(f.finalPath, "is {} now, which is never replaced", fileKindName(st.st_mode));
    if (::rename(from.c_str(), f.targetPath.c_str()) != 0) fail(f.finalPath, "cannot replace file: {}", errnoText(errno));
    unregisterTempFile(from);
    from.clear();
}

/// Copies @p f's bytes into the device or FIFO it is meant for.
void writeSpecial(AtomicFile::Finished& f) {
    const int out = ::open(f.targetPath.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
    if (out < 0) {
        if (errno == ENXIO) fail(f.finalPath, "is a FIFO that no process reads");
        fail(f.finalPath, "cannot open: {}", errnoText(errno));
    }
    std::unique_ptr<int, void (*)(int*)> guard(new int(out), [](int* fd) { ::close(*fd), delete fd; });
    if (int flags = ::fcntl(out, F_GETFL); flags >= 0) ::fcntl(out, F_SETFL, flags & ~O_NONBLOCK);
    std::vector<uint8_t> block(1 << 20);
    for (off_t offset = 0;;) {
        const ssize_t n = ::pread(f.fd, block.data(), block.size(), offset);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) fail(f.finalPath, "cannot read the finished output back: {}", errnoText(errno));
        if (n == 0) break;
        for (ssize_t done = 0; done < n;) {
            const ssize_t w = ::write(out, block.data() + done, size_t(n - done));
            if (w < 0 && errno == EINTR) continue;
            if (w <= 0) fail(f.finalPath, "write failed: {}", errnoText(w < 0 ? errno : EIO));
            done += w;
        }
        offset += n;
    }
}

/// Puts a regular file in place: a link under the final name when it is free, else a staged
/// link renamed over the old file; a named temporary is renamed.
void placeRegular(AtomicFile::Finished& f) {
    if (!f.tempName.empty()) return renameOver(f, f.tempName);
    if (f.staged.empty()) {
        const int err = linkAnonymous(f.fd, f.targetPath);
        if (err == 0) return;
        if (err != EEXIST) fail(f.finalPath, "cannot create file: {}", errnoText(err));
        stage(f);
    }
    renameOver(f, f.staged);
}

/// Makes @p f's new name durable: fsync of the directory that holds it (the data was synced
/// before it was linked). A device needs none.
void syncDirectoryOf(const AtomicFile::Finished& f) {
    if (!f.sync || f.target != AtomicFile::Target::Regular) return;
    std::string dir = std::filesystem::path(f.targetPath).parent_path().string();
    if (dir.empty()) dir = ".";
    const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    const int err = fd < 0 || ::fsync(fd) != 0 ? errno : 0;
    if (fd >= 0) ::close(fd);
    // EINVAL: a file system that cannot sync directories; the rename is as durable as it gets there.
    if (err != 0 && err != EINVAL) fail(f.finalPath, "cannot sync its directory {}: {}", dir, errnoText(err));
}

void place(AtomicFile::Finished& f) {
    SignalsHeld held;
    if (f.target == AtomicFile::Target::Special) writeSpecial(f);
    else placeRegular(f);
    syncDirectoryOf(f);
}

/// What AtomicFile does with @p path: the file to replace (symbolic links followed) and how.
bool isSpecialMode(mode_t mode) { return S_ISCHR(mode) || S_ISFIFO(mode); }

AtomicFile::Target inspectTarget(const std::string& path, std::string& resolved) {
    resolved = path;
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) {
        if (errno != ENOENT) fail(path, "cannot create file: {}", errnoText(errno));
        if (::lstat(path.c_str(), &st) == 0) fail(path, "is a symbolic link to a missing file");
        return AtomicFile::Target::Regular;
    }
    if (std::optional<std::string> input = recordedInput(st.st_dev, st.st_ino))
        fail(path, "is also an input of this run ({}); refusing to overwrite it", *input);
    if (isSpecialMode(st.st_mode)) return AtomicFile::Target::Special;
    if (!S_ISREG(st.st_mode))
        fail(path, "is {}; outputs are regular files, character devices or FIFOs", fileKindName(st.st_mode));
    if (::lstat(path.c_str(), &st) == 0 && S_ISLNK(st.st_mode)) {
        std::error_code ec;
        std::filesystem::path real = std::filesystem::canonical(path, ec);
        if (!ec) resolved = real.string();
    }
    return AtomicFile::Target::Regular;
}

}  // namespace

bool anonymousFilesDisabled() {
    const char* value = std::getenv("PENUMBRA_NO_TMPFILE");
    return value && *value && std::strcmp(value, "0") != 0;
}

// ---------------------------------------------------------------------------------------------
// AtomicFile

bool AtomicFile::writtenInto(const std::string& path) {
    struct stat st {};
    return ::stat(path.c_str(), &st) == 0 && isSpecialMode(st.st_mode);
}

AtomicFile::AtomicFile(std::string finalPath) : finalPath_(std::move(finalPath)) {
    if (finalPath_.empty()) throw InputError("cannot create file: the output path is empty");
    target_ = inspectTarget(finalPath_, targetPath_);
    // A device's data waits in the temp directory; a regular file's beside its final name, so
    // that linking and renaming never cross a file system.
    std::string dir;
    if (target_ == Target::Special) {
        std::error_code ec;
        dir = std::filesystem::temp_directory_path(ec).string();
        if (ec) dir = "/tmp";
    } else dir = std::filesystem::path(targetPath_).parent_path().string();
    createTemporary(dir.empty() ? "." : dir);
}

void AtomicFile::createTemporary(const std::string& dir) {
    if (!anonymousFilesDisabled() && procFdWorks()) {
        fd_ = ::open(dir.c_str(), O_RDWR | O_TMPFILE | O_CLOEXEC, 0666);
        if (fd_ >= 0) {
            tempPath_ = procPath(fd_);
            return;
        }
        // EISDIR / EOPNOTSUPP / EINVAL: no O_TMPFILE here (old kernel, some network file systems).
        if (errno != EISDIR && errno != EOPNOTSUPP && errno != EINVAL)
            fail(finalPath_, "cannot create file: {}", errnoText(errno));
    }
    const std::string base = target_ == Target::Special
                                 ? (std::filesystem::path(dir) / std::filesystem::path(targetPath_).filename()).string()
                                 : targetPath_;
    for (int attempt = 0;; ++attempt) {
        tempName_ = uniqueName(base);
        // Registered before it exists, so no signal can come between creating and registering.
        registerTempFile(tempName_);
        fd_ = ::open(tempName_.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd_ >= 0) {
            tempPath_ = tempName_;
            return;
        }
        const int err = errno;
        unregisterTempFile(tempName_);
        tempName_.clear();
        if (err != EEXIST || attempt >= 1000) fail(finalPath_, "cannot create file: {}", errnoText(err));
    }
}

AtomicFile::~AtomicFile() {
    if (!committed_) discard();
}

void AtomicFile::discard() noexcept {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    if (!tempName_.empty()) {
        ::unlink(tempName_.c_str());
        unregisterTempFile(tempName_);
        tempName_.clear();
    }
}

void AtomicFile::write(const void* data, size_t bytes) {
    if (committed_ || fd_ < 0) fail(finalPath_, "write failed: the file is already closed");
    if (failed_) fail(finalPath_, "write failed: an earlier write to this file failed");
    if (buffer_.empty()) buffer_.resize(kBufferBytes);

    const auto* src = static_cast<const uint8_t*>(data);
    while (bytes > 0) {
        // Large writes with an empty buffer skip the copy entirely.
        if (used_ == 0 && bytes >= buffer_.size()) {
            size_t chunk = bytes - bytes % buffer_.size();
            size_t done = 0;
            while (done < chunk) {
                ssize_t n = ::write(fd_, src + done, chunk - done);
                if (n < 0 && errno == EINTR) continue;
                if (n <= 0) {
                    int err = n < 0 ? errno : EIO;
                    failed_ = true;
                    fail(finalPath_, "write failed: {} (needed {} more bytes)", errnoText(err), bytes - done);
                }
                done += static_cast<size_t>(n);
            }
            src += chunk;
            bytes -= chunk;
            continue;
        }
        size_t take = std::min(bytes, buffer_.size() - used_);
        std::memcpy(buffer_.data() + used_, src, take);
        used_ += take;
        src += take;
        bytes -= take;
        if (used_ == buffer_.size()) flushBuffer(bytes);
    }
}

/// Writes the buffer out. @p pendingAfter is what the caller still has to write after the
/// buffer, so the error message can say how much did not fit.
void AtomicFile::flushBuffer(size_t pendingAfter) {
    size_t done = 0;
    while (done < used_) {
        ssize_t n = ::write(fd_, buffer_.data() + done, used_ - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            int err = n < 0 ? errno : EIO;
            failed_ = true;
            fail(finalPath_, "write failed: {} (needed {} more bytes)", errnoText(err), used_ - done + pendingAfter);
        }
        done += static_cast<size_t>(n);
    }
    used_ = 0;
}

void AtomicFile::commit() {
    if (committed_) return;
    if (failed_) fail(finalPath_, "cannot commit: an earlier write to this file failed");
    try {
        if (used_ > 0) flushBuffer(0);
        // Data before name: a crash after the link must not find the name with missing bytes.
        if (sync_ && target_ == Target::Regular && ::fsync(fd_) != 0)
            fail(finalPath_, "write failed: cannot sync the file: {}", errnoText(errno));
        auto f = std::make_unique<Finished>();
        f->finalPath = finalPath_, f->targetPath = targetPath_, f->target = target_, f->sync = sync_;
        if (!tempName_.empty()) {
            // A library writing by name may have failed and removed it without our knowing.
            struct stat st {};
            if (::stat(tempName_.c_str(), &st) != 0)
                fail(finalPath_, "output was not written (temporary file {} is missing)", tempName_);
            // Some file systems (NFS, quota-enforcing ones) only report a failed write at close;
            // these are the ones without O_TMPFILE. A device's data is still to be read back.
            if (target_ == Target::Regular) {
                const int fd = std::exchange(fd_, -1);
                if (::close(fd) != 0 && errno != EINTR) fail(finalPath_, "write failed: {}", errnoText(errno));
            }
        }
        f->fd = std::exchange(fd_, -1);
        f->tempName = std::exchange(tempName_, std::string());
        {
            std::lock_guard lock(g_setMutex);
            if (g_openSet) {
                g_openSet->files_.push_back(std::move(f));
                committed_ = true;
                return;
            }
        }
        place(*f);
    } catch (...) {
        discard();
        throw;
    }
    committed_ = true;
}

// ---------------------------------------------------------------------------------------------
// OutputSet

OutputSet::OutputSet() {
    std::lock_guard lock(g_setMutex);
    if (g_openSet) throw std::logic_error("OutputSet: only one set may be open at a time");
    g_openSet = this;
}

OutputSet::~OutputSet() {
    {
        std::lock_guard lock(g_setMutex);
        if (g_openSet == this) g_openSet = nullptr;
    }
    if (open_) removeMadeDirectories();  // never committed: a later output of the job failed
}

void OutputSet::removeMadeDirectories() noexcept {
    for (auto it = madeDirectories_.rbegin(); it != madeDirectories_.rend(); ++it) {
        ::rmdir(it->c_str());  // fails, as it should, for a folder something else has filled
        unregisterTempFile(*it);
    }
    madeDirectories_.clear();
}

std::vector<std::string> OutputSet::paths() const {
    std::vector<std::string> out;
    for (const auto& f : files_) out.push_back(f->finalPath);
    return out;
}

void OutputSet::commit() {
    {
        std::lock_guard lock(g_setMutex);
        if (g_openSet == this) g_openSet = nullptr;
    }
    if (!open_) return;
    open_ = false;
    SignalsHeld held;
    try {
        // Two files of the set for one path (a stats file named like the camera's PNG): one would
        // replace the other without a word. The up-front checks cannot know every file a receiver
        // kind derives from the output; this one sees them all.
        // Compared as comparablePath() spells them: ./o2/a.png, $PWD/o2/a.png and L/a.png (L a
        // link to o2) are one file.
        std::vector<std::string> keys;
        for (const auto& f : files_) keys.push_back(comparablePath(f->targetPath));
        for (size_t i = 0; i < files_.size(); ++i)
            for (size_t j = 0; j < i; ++j)
                if (files_[i]->target == AtomicFile::Target::Regular && keys[i] == keys[j])
                    fail(files_[i]->finalPath, "is named for two outputs of this bake; give each its own file");
        // Something other than a file now standing at a target (a dump folder made at the
        // preview's name) is refused before any file of the set is in place, not after the first.
        for (const auto& f : files_) {
            struct stat st {};
            if (f->target == AtomicFile::Target::Regular && ::lstat(f->targetPath.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
                fail(f->finalPath, "is {} now, which is never replaced", fileKindName(st.st_mode));
        }
        // Every rename is staged first, so a failure to link one leaves no file of the set in place.
        for (auto& f : files_)
            if (f->target == AtomicFile::Target::Regular && f->tempName.empty() && ::access(f->targetPath.c_str(), F_OK) == 0)
                stage(*f);
        for (auto& f : files_)
            if (f->target == AtomicFile::Target::Special) writeSpecial(*f);
        for (auto& f : files_)
            if (f->target == AtomicFile::Target::Regular) placeRegular(*f);
        for (auto& f : files_) syncDirectoryOf(*f);
    } catch (...) {
        files_.clear();  // discards what is not in place, staged names included
        removeMadeDirectories();
        throw;
    }
    files_.clear();
    for (const std::string& dir : madeDirectories_) unregisterTempFile(dir);  // they hold outputs now
    madeDirectories_.clear();
}

// ---------------------------------------------------------------------------------------------

void writeFileAtomically(const std::string& path, std::span<const uint8_t> bytes, FileSync sync) {
    AtomicFile file(path);
    if (sync == FileSync::Durable) file.syncOnCommit();
    if (!bytes.empty()) file.write(bytes.data(), bytes.size());
    file.commit();
}

void ensureParentDirectory(const std::string& path) {
    std::filesystem::path parent = std::filesystem::path(path).parent_path();
    if (parent.empty()) return;
    std::error_code ec;
    std::vector<std::string> missing;  // the folders this call makes, innermost first
    for (std::filesystem::path p = parent; !p.empty() && !std::filesystem::exists(p, ec); p = p.parent_path()) {
        missing.push_back(p.string());
        if (p == p.parent_path()) break;
    }
    std::filesystem::create_directories(parent, ec);
    if (!missing.empty() && !ec) {
        std::lock_guard lock(g_setMutex);
        if (g_openSet) {
            // Innermost first in the registry, so that a signal empties them in order.
            for (const std::string& dir : missing) registerTempFile(dir);
            g_openSet->madeDirectories_.insert(g_openSet->madeDirectories_.end(), missing.rbegin(), missing.rend());
        }
    }
    if (ec) fail(path, "cannot create directory {}: {}", parent.string(), ec.message());
    // create_directories() reports no error when the parent exists as a regular file on some
    // library versions; check explicitly so the message is about the directory, not the file.
    if (!std::filesystem::is_directory(parent, ec))
        fail(path, "cannot create directory {}: {}", parent.string(), errnoText(ENOTDIR));
}

namespace {

/// @p path, or the nearest of its parents that exists (where a file or folder under it is made).
std::filesystem::path nearestExisting(std::filesystem::path path) {
    std::error_code ec;
    while (!std::filesystem::exists(path, ec) && path != path.root_path()) path = path.parent_path();
    return path;
}

}  // namespace

void checkOutputPath(const std::string& path) {
    if (path.empty()) throw InputError("cannot create file: the output path is empty");
    std::string resolved;
    if (inspectTarget(path, resolved) == AtomicFile::Target::Special) return;
    // The nearest existing directory above the file must be one we can create files in.
    std::error_code ec;
    const std::filesystem::path dir = nearestExisting(std::filesystem::absolute(resolved).parent_path());
    if (!std::filesystem::is_directory(dir, ec)) fail(path, "cannot create file: {} is not a directory", dir.string());
    if (::access(dir.c_str(), W_OK | X_OK) != 0) fail(path, "cannot create file in {}: {}", dir.string(), errnoText(errno));
}

void checkOutputFolder(const std::string& path) {
    if (path.empty()) throw InputError("cannot create a folder: the path is empty");
    // The folder itself when it exists, else the nearest directory above it, where it will be made.
    std::error_code ec;
    const std::filesystem::path dir = nearestExisting(std::filesystem::absolute(path));
    if (!std::filesystem::is_directory(dir, ec)) fail(path, "cannot be made a folder: {} is not a directory", dir.string());
    if (::access(dir.c_str(), W_OK | X_OK) != 0) fail(path, "cannot write into {}: {}", dir.string(), errnoText(errno));
}

}  // namespace penumbra
