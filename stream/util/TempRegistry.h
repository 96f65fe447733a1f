#pragma once
/// @file TempRegistry.h
/// @brief The names of temporary files that exist for a moment, removed by a signal handler if
/// the process is interrupted in that moment.
///
/// Most temporaries have no name at all (O_TMPFILE: AtomicFile.h, BucketFiles.h), so no signal
/// can leave them behind. Names exist only where the file system lacks O_TMPFILE, and for the
/// microseconds in which a finished output is linked under a temporary name before it is renamed
/// over the file it replaces. Those names are registered here, and the handlers that
/// installCleanupSignalHandlers() sets for SIGINT, SIGTERM, SIGHUP and SIGQUIT unlink them before
/// the process dies. SIGKILL cannot be handled: it can leave a name only from those two cases.
///
/// A fixed table of fixed-size path buffers, claimed with atomics, so that the signal handler
/// neither allocates nor takes locks. Paths longer than the slot size, or registrations beyond
/// the table's capacity, are silently not tracked (the owner still removes them on unwinding).

#include <string>

namespace penumbra {

/// @brief Records @p path for removal by removeRegisteredTempFiles().
void registerTempFile(const std::string& path);
/// @brief Forgets @p path (after it has been renamed or removed by its owner).
void unregisterTempFile(const std::string& path);
/// @brief unlink()s every registered file (rmdir() for a folder, which goes only if empty) and
/// forgets it. Only async-signal-safe calls are made, so this may run inside a signal handler.
void removeRegisteredTempFiles() noexcept;
/// @brief Installs handlers for SIGINT, SIGTERM, SIGHUP and SIGQUIT that remove registered temp
/// files and then re-raise the signal with its default action (so the exit status still says
/// which signal ended the process). A signal the parent set to be ignored stays ignored.
/// Idempotent.
void installCleanupSignalHandlers();

/// @brief For a library caller (the Python module), while it lives: the same cleanup for SIGTERM,
/// SIGHUP and SIGQUIT, but only where the process left the default action (which ends it anyway),
/// so that a handler the caller installed, and SIGINT (Python's KeyboardInterrupt), are untouched.
/// The previous actions come back when it ends.
class ScopedSignalCleanup {
public:
    ScopedSignalCleanup();
    ~ScopedSignalCleanup();
    ScopedSignalCleanup(const ScopedSignalCleanup&) = delete;
    ScopedSignalCleanup& operator=(const ScopedSignalCleanup&) = delete;

private:
    static constexpr int kSignals = 3;
    bool installed_[kSignals] = {};
};

}  // namespace penumbra
