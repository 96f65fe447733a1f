#include "stream/AtomicFile.h"

#include "stream/Error.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <system_error>

namespace penumbra {

namespace {

/// Write-behind buffer size. Big enough that syscall overhead is irrelevant for multi-GB
/// outputs, small enough not to matter for the memory budget.
constexpr size_t kBufferBytes = 256 * 1024;

std::string errnoText(int err) { return std::error_code(err, std::generic_category()).message(); }

}  // namespace

// ---------------------------------------------------------------------------------------------
// AtomicFile

AtomicFile::AtomicFile(std::string finalPath) : finalPath_(std::move(finalPath)) {
    if (finalPath_.empty()) throw InputError("cannot create file: the output path is empty");

    // The pid keeps concurrent penumbra processes apart; the counter keeps several outputs of
    // one process (or one path written twice) apart. O_EXCL makes a stale leftover from a
    // killed run harmless: we just take the next number.
    static std::atomic<uint64_t> counter{0};
    for (int attempt = 0;; ++attempt) {
        tempPath_ = fmt::format("{}.tmp-{}-{}", finalPath_, static_cast<long>(::getpid()),
                                counter.fetch_add(1));
        // Register before creating so there is no window in which a signal would leave an
        // unregistered file behind; unlinking a name that was never created is harmless.
        registerTempFile(tempPath_);
        fd_ = ::open(tempPath_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd_ >= 0) return;
        int err = errno;
        unregisterTempFile(tempPath_);
        if (err == EEXIST && attempt < 1000) continue;
        tempPath_.clear();
        fail(finalPath_, "cannot create file: {}", errnoText(err));
    }
}

AtomicFile::~AtomicFile() {
    if (!committed_) discard();
}

void AtomicFile::discard() noexcept {
    if (fd_ >= 0) {
        ::close(fd_);
        fd_ = -1;
    }
    if (!tempPath_.empty()) {
        ::unlink(tempPath_.c_str());
        unregisterTempFile(tempPath_);
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
                    fail(finalPath_, "write failed: {} (needed {} more bytes)", errnoText(err),
                         bytes - done);
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
            fail(finalPath_, "write failed: {} (needed {} more bytes)", errnoText(err),
                 used_ - done + pendingAfter);
        }
        done += static_cast<size_t>(n);
    }
    used_ = 0;
}

void AtomicFile::closeFd() {
    int fd = fd_;
    fd_ = -1;
    // Some file systems (NFS, quota-enforcing ones) only report a failed write at close.
    // EINTR from close on Linux still releases the descriptor, so it is not an error.
    if (::close(fd) != 0 && errno != EINTR) {
        failed_ = true;
        fail(finalPath_, "write failed: {}", errnoText(errno));
    }
}

void AtomicFile::commit() {
    if (committed_) return;
    if (failed_) fail(finalPath_, "cannot commit: an earlier write to this file failed");
    try {
        if (used_ > 0) flushBuffer(0);
        if (fd_ >= 0) closeFd();
        // A library writing by name may have failed without us knowing; the file must at
        // least still be there.
        struct stat st {};
        if (::stat(tempPath_.c_str(), &st) != 0)
            fail(finalPath_, "output was not written (temporary file {} is missing)", tempPath_);
        if (::rename(tempPath_.c_str(), finalPath_.c_str()) != 0)
            fail(finalPath_, "cannot replace file: {}", errnoText(errno));
    } catch (...) {
        discard();
        throw;
    }
    unregisterTempFile(tempPath_);
    committed_ = true;
}

void writeFileAtomically(const std::string& path, std::span<const uint8_t> bytes) {
    AtomicFile file(path);
    if (!bytes.empty()) file.write(bytes.data(), bytes.size());
    file.commit();
}

void ensureParentDirectory(const std::string& path) {
    std::filesystem::path parent = std::filesystem::path(path).parent_path();
    if (parent.empty()) return;
    std::error_code ec;
    std::filesystem::create_directories(parent, ec);
    if (ec) fail(path, "cannot create directory {}: {}", parent.string(), ec.message());
    // create_directories() reports no error when the parent exists as a regular file on some
    // library versions; check explicitly so the message is about the directory, not the file.
    if (!std::filesystem::is_directory(parent, ec))
        fail(path, "cannot create directory {}: {}", parent.string(), errnoText(ENOTDIR));
}

// ---------------------------------------------------------------------------------------------
// Temp-file registry

namespace {

constexpr size_t kRegistrySlots = 64;
constexpr size_t kRegistryPathBytes = 4096;

enum SlotState : int { kSlotFree = 0, kSlotBusy = 1, kSlotUsed = 2 };

/// One registered path. `state` is the only synchronisation: a slot's path is written while
/// the slot is Busy and read only while it is Used, so the signal handler never sees a torn
/// path and never has to wait.
struct RegistrySlot {
    std::atomic<int> state{kSlotFree};
    char path[kRegistryPathBytes];
};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler relies on lock-free atomics");

RegistrySlot g_registry[kRegistrySlots];

}  // namespace

void registerTempFile(const std::string& path) {
    if (path.empty() || path.size() >= kRegistryPathBytes) return;
    for (auto& slot : g_registry) {
        int expected = kSlotFree;
        if (!slot.state.compare_exchange_strong(expected, kSlotBusy)) continue;
        std::memcpy(slot.path, path.c_str(), path.size() + 1);
        slot.state.store(kSlotUsed, std::memory_order_release);
        return;
    }
}

void unregisterTempFile(const std::string& path) {
    if (path.empty() || path.size() >= kRegistryPathBytes) return;
    for (auto& slot : g_registry) {
        if (slot.state.load(std::memory_order_acquire) != kSlotUsed) continue;
        if (std::strcmp(slot.path, path.c_str()) != 0) continue;
        int expected = kSlotUsed;
        if (slot.state.compare_exchange_strong(expected, kSlotBusy)) {
            slot.path[0] = '\0';
            slot.state.store(kSlotFree, std::memory_order_release);
            return;
        }
    }
}

void removeRegisteredTempFiles() noexcept {
    for (auto& slot : g_registry) {
        int expected = kSlotUsed;
        // A Busy slot is being (un)registered by another thread right now; skipping it is the
        // price of never blocking in a signal handler.
        if (!slot.state.compare_exchange_strong(expected, kSlotBusy)) continue;
        ::unlink(slot.path);
        slot.path[0] = '\0';
        slot.state.store(kSlotFree, std::memory_order_release);
    }
}

namespace {

extern "C" void cleanupSignalHandler(int sig) {
    int savedErrno = errno;
    removeRegisteredTempFiles();
    // SA_RESETHAND already restored the default action; the signal is blocked while we are in
    // the handler, so the re-raised one is delivered (and kills us) as soon as we return.
    ::raise(sig);
    errno = savedErrno;
}

}  // namespace

void installCleanupSignalHandlers() {
    struct sigaction action {};
    action.sa_handler = cleanupSignalHandler;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESETHAND;
    for (int sig : {SIGINT, SIGTERM}) {
        // Respect an "ignore" inherited from the parent (nohup, background jobs).
        struct sigaction old {};
        if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
        ::sigaction(sig, &action, nullptr);
    }
}

}  // namespace penumbra
