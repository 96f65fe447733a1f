#pragma once
/// @file AtomicFile.h
/// @brief Output files that are either complete or absent, never half written.
///
/// Every file penumbra produces (EXR, PNG, .npy, stats) is first written to a temporary file
/// next to its final path and renamed over it only once every byte has been written and the
/// file closed without error. rename(2) within one directory is atomic, so a reader, a crash,
/// a full disk or a Ctrl-C can only ever observe the old file or the complete new one.
///
/// Temporary files are recorded in a small process-wide registry so that a SIGINT/SIGTERM
/// handler (installCleanupSignalHandlers()) can delete them before the process dies; a
/// destructor never runs in that case.

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

/// @brief A file written under a temporary name and renamed into place by commit().
///
/// Two ways to fill it:
///  - call write() any number of times (buffered; errors are reported with the final path);
///  - or hand tempPath() to a library that opens files by name itself (OpenEXR, stb), then
///    call commit(), which checks the file exists and renames it.
///
/// Not thread safe; one writer per object.
class AtomicFile {
public:
    /// @brief Creates the temporary file `finalPath + ".tmp-<pid>-<counter>"` in the same
    /// directory as @p finalPath (so the final rename never crosses a file system).
    /// @param finalPath where the file appears on commit(). Its directory must already exist;
    ///        see ensureParentDirectory().
    /// @throw InputError "FINAL: cannot create file: REASON" when the directory is missing or
    ///        not writable.
    explicit AtomicFile(std::string finalPath);
    ~AtomicFile();  ///< Removes the temporary file unless commit() succeeded.

    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    /// The final path given to the constructor.
    const std::string& finalPath() const { return finalPath_; }
    /// The temporary file's path, for libraries that write by file name.
    const std::string& tempPath() const { return tempPath_; }

    /// @brief Appends @p bytes bytes from @p data.
    /// @throw InputError "FINAL: write failed: REASON (needed N more bytes)" on an I/O error
    ///        such as a full disk. After a failure the object only accepts destruction.
    void write(const void* data, size_t bytes);

    /// @brief Flushes, closes (checking for deferred errors) and renames the temporary file to
    /// the final path. There is deliberately no fsync: atomicity against other readers and
    /// against our own crashes is what matters, not durability across power loss.
    /// @throw InputError naming the final path on any failure; the temporary file is removed.
    void commit();

    /// True once commit() has succeeded.
    bool committed() const { return committed_; }

private:
    void flushBuffer(size_t pendingAfter);
    void closeFd();
    void discard() noexcept;

    std::string finalPath_;
    std::string tempPath_;
    std::vector<uint8_t> buffer_;
    size_t used_ = 0;
    int fd_ = -1;
    bool failed_ = false;
    bool committed_ = false;
};

/// @brief Writes @p bytes to @p path atomically (temp file + rename).
/// @throw InputError naming @p path on failure.
void writeFileAtomically(const std::string& path, std::span<const uint8_t> bytes);

/// @brief Creates the parent directory of @p path (and its parents) if missing.
/// @throw InputError "PATH: cannot create directory DIR: REASON" on failure.
void ensureParentDirectory(const std::string& path);

/// @name Temp-file registry for signal-time cleanup
/// A fixed table of fixed-size path buffers, claimed with atomics, so that the signal handler
/// neither allocates nor takes locks. Paths longer than the slot size, or registrations beyond
/// the table's capacity, are silently not tracked (the file is still removed by its owner's
/// destructor on normal unwinding).
/// @{

/// @brief Records @p path for removal by removeRegisteredTempFiles().
void registerTempFile(const std::string& path);
/// @brief Forgets @p path (after it has been renamed or removed by its owner).
void unregisterTempFile(const std::string& path);
/// @brief unlink()s every registered file and forgets it. Only async-signal-safe calls are
/// made, so this may run inside a signal handler.
void removeRegisteredTempFiles() noexcept;
/// @brief Installs SIGINT and SIGTERM handlers that remove registered temp files and then
/// re-raise the signal with its default action (so the exit status still says "killed by
/// SIGINT"). Idempotent.
void installCleanupSignalHandlers();

/// @}

}  // namespace penumbra
