#pragma once
/// @file AtomicFile.h
/// @brief Output files that are either complete or absent, never half written, and sets of
/// outputs that are committed together.
///
/// A file is written as an anonymous file (O_TMPFILE) in the directory of its final path, the way
/// the bucket files are, and linked into place (linkat) only once every byte is written. It has
/// no name until then, so no signal, SIGKILL included, and no crash can leave a temporary behind.
/// Where the final path already exists, the finished file is linked under a temporary name and
/// renamed over it, so a reader sees the old file or the new one and never neither; that name
/// exists for microseconds, with catchable signals blocked, and is registered (TempRegistry.h).
/// File systems without O_TMPFILE (and `PENUMBRA_NO_TMPFILE=1`, which forces this for tests)
/// get the classic named temporary `FINAL.tmp-<pid>-<n>`, registered and renamed into place.
///
/// What a final path may be:
///  - a regular file or a new name: replaced atomically as above (a symbolic link is followed,
///    and the file it points to is replaced);
///  - a character device or a FIFO (`-o /dev/null`): written directly on commit, never renamed
///    over (that would turn /dev/null into a plain file for the whole machine); the data waits in
///    an anonymous file in the temp directory until then;
///  - a directory, a block device, a socket, or a file this process read as an input (compared
///    by device and inode, InputFile.h): refused.
///
/// OutputSet groups the outputs of one job: while a set is open, commit() only finishes a file,
/// and the set puts every file in place at once, or none if one of them fails first.

#include "stream/util/TempRegistry.h"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

/// @brief A file written out of sight and put into place by commit().
///
/// Two ways to fill it:
///  - call write() any number of times (buffered; errors are reported with the final path);
///  - or hand tempPath() to a library that opens files by name itself (OpenEXR, stb), then call
///    commit().
///
/// Not thread safe; one writer per object.
class AtomicFile {
public:
    /// @brief Creates the temporary file for @p finalPath.
    /// @param finalPath where the file appears on commit(). Its directory must already exist;
    ///        see ensureParentDirectory().
    /// @throw InputError "FINAL: cannot create file: REASON" when the directory is missing or
    ///        not writable, and "FINAL: is a directory" (an input of this run, a block device, a
    ///        socket) when the path names something that must not be replaced.
    explicit AtomicFile(std::string finalPath);
    ~AtomicFile();  ///< Discards the temporary unless commit() succeeded.

    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    /// The final path given to the constructor.
    const std::string& finalPath() const { return finalPath_; }
    /// A name by which libraries can open the temporary for writing: `/proc/self/fd/N` for an
    /// anonymous file, else the temporary's own name.
    const std::string& tempPath() const { return tempPath_; }
    /// The open descriptor of the temporary (read-write), for positioned writes (pwrite). Valid
    /// until commit(); never close it.
    int descriptor() const { return fd_; }

    /// @brief Appends @p bytes bytes from @p data.
    /// @throw InputError "FINAL: write failed: REASON (needed N more bytes)" on an I/O error
    ///        such as a full disk. After a failure the object only accepts destruction.
    void write(const void* data, size_t bytes);

    /// @brief Asks commit() to make the file durable: its data is fsync()ed before it gets its
    /// name, and its directory after, so that a crash of the machine (not only of the process)
    /// leaves the old file or the complete new one. For checkpoints and shard files, whose whole
    /// point is to survive what kills the bake; outputs skip it (atomicity is what they need).
    void syncOnCommit() { sync_ = true; }

    /// @brief Flushes the file and puts it in place (or, while an OutputSet is open, hands it to
    /// the set). There is no fsync unless syncOnCommit() asked for it.
    /// @throw InputError naming the final path on any failure; nothing is left behind.
    void commit();

    /// True once commit() has succeeded.
    bool committed() const { return committed_; }

    /// How a final path is written (see the file comment).
    enum class Target { Regular, Special };
    /// @brief Whether @p path names a character device or a FIFO, which an output is written into
    /// (Target::Special) rather than replaced.
    static bool writtenInto(const std::string& path);
    /// One finished file waiting to be put in place (OutputSet's; opaque elsewhere).
    struct Finished;

private:
    void createTemporary(const std::string& dir);
    void flushBuffer(size_t pendingAfter);
    void discard() noexcept;

    std::string finalPath_;
    std::string targetPath_;  ///< finalPath_ with symbolic links resolved
    std::string tempPath_;
    std::string tempName_;    ///< the named temporary, in the fallback only
    Target target_ = Target::Regular;
    std::vector<uint8_t> buffer_;
    size_t used_ = 0;
    int fd_ = -1;
    bool failed_ = false;
    bool committed_ = false;
    bool sync_ = false;
};

/// @brief The outputs of one job, committed together: while the set is open, AtomicFile::commit()
/// (on any thread) only finishes a file; commit() then puts them all in place, the files written
/// into devices and FIFOs first (the likeliest to fail), then the links and renames. If anything
/// fails before the first file is in place, none is. Destroying an uncommitted set discards every
/// file. Sets do not nest: a second one open at the same time is an error.
class OutputSet {
public:
    OutputSet();
    ~OutputSet();
    OutputSet(const OutputSet&) = delete;
    OutputSet& operator=(const OutputSet&) = delete;

    /// @brief Puts every finished file in place and closes the set.
    /// @throw InputError naming the file that failed.
    void commit();

    /// Files finished so far (for tests).
    size_t size() const { return files_.size(); }
    /// The paths of the files finished so far, in the order they were finished (what commit()
    /// puts in place; the summary and the stats name them).
    std::vector<std::string> paths() const;

private:
    friend class AtomicFile;
    friend void ensureParentDirectory(const std::string& path);
    /// Removes the folders made for the set's files (innermost first, each only if empty): the
    /// set was not put in place.
    void removeMadeDirectories() noexcept;
    std::vector<std::unique_ptr<AtomicFile::Finished>> files_;
    /// Folders ensureParentDirectory() made while the set was open, outermost first; registered
    /// with TempRegistry.h until the set is in place, so that a signal before then removes them.
    std::vector<std::string> madeDirectories_;
    bool open_ = true;
};

/// @brief Whether writeFileAtomically() makes the file durable (AtomicFile::syncOnCommit).
enum class FileSync { None, Durable };

/// @brief Writes @p bytes to @p path atomically (see AtomicFile), with fsync when @p sync asks.
/// @throw InputError naming @p path on failure.
void writeFileAtomically(const std::string& path, std::span<const uint8_t> bytes, FileSync sync = FileSync::None);

/// @brief Creates the parent directory of @p path (and its parents) if missing. While an
/// OutputSet is open the folders it makes belong to the set: they are removed, if still empty,
/// when the set is not put in place or a termination signal ends the process first.
/// @throw InputError "PATH: cannot create directory DIR: REASON" on failure.
void ensureParentDirectory(const std::string& path);

/// @brief Checks, before any work, that @p path can be written as an output: it is not a
/// directory, an input, a block device or a socket (as AtomicFile refuses), and its directory
/// exists or can be made and is writable.
/// @throw InputError naming @p path.
void checkOutputPath(const std::string& path);

/// @brief The same check for a folder an output goes into (checkpoints, shard files, a dump): it,
/// or the nearest directory above it where it will be made, must be a directory this process can
/// write into (a read-only file system fails the check).
/// @throw InputError "PATH: cannot be made a folder: X is not a directory" or "PATH: cannot write
///        into X: REASON".
void checkOutputFolder(const std::string& path);

/// @brief True when `PENUMBRA_NO_TMPFILE` is set (to anything but "" or "0"): every anonymous
/// file (outputs, bucket files) is then made the way file systems without O_TMPFILE need, for
/// tests of that fallback.
bool anonymousFilesDisabled();

}  // namespace penumbra
