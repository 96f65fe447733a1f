#pragma once
/// @file InputFile.h
/// @brief Inputs are regular files. Opening one refuses FIFOs, devices, sockets and directories,
/// which would hang a reader or be read until memory runs out (`/dev/zero` as an OBJ), and
/// records the file's identity (device and inode), so that an output is never written over an
/// input, whatever name it is given (AtomicFile.h asks recordedInput()).

#include <sys/types.h>

#include <cstdio>
#include <optional>
#include <string>

namespace penumbra {

/// @brief Opens @p path for reading if it is a regular file (symbolic links are followed) and
/// records it as an input of the current InputScope. The file is opened without blocking, so a
/// FIFO without a writer is refused at once instead of waited for.
/// @return a blocking descriptor (O_CLOEXEC), owned by the caller.
/// @throw InputError "PATH: cannot open: REASON" or "PATH: is a FIFO, not a regular file" (a
///        directory, a character or block device, a socket likewise).
int openInputFile(const std::string& path);

/// @brief openInputFile() as a stdio stream opened "rb", owned by the caller (fclose).
/// @throw InputError as openInputFile().
std::FILE* openInputStream(const std::string& path);

/// @brief Checks that @p path is a regular file and records it, without keeping it open: for
/// readers that open the file themselves (tinygltf, the OBJ reader).
/// @throw InputError as openInputFile().
void checkInputFile(const std::string& path);

/// @brief Records @p path as an input of the current InputScope when it is a regular file, and
/// does nothing otherwise: for files an input refers to that the run does not read itself (a
/// glTF's textures, which a vertex bake's copy still refers to), so that no output replaces them.
void recordReferencedFile(const std::string& path);

/// @brief One version of a file: its device, inode, size and modification time. A file replaced
/// (renamed over, as `penumbra generate` writes) or rewritten in place has another, even at the
/// same size. Readers that read a file once per pass keep the first pass's stamp and require the
/// same at each later pass: receivers from one version and shadows from another were baked with
/// exit 0.
struct FileStamp {
    dev_t device = 0;
    ino_t inode = 0;
    int64_t size = 0, modifiedSeconds = 0, modifiedNanoseconds = 0;
    bool operator==(const FileStamp&) const = default;

    /// @throw InputError "PATH: cannot stat: REASON".
    static FileStamp of(const std::string& path);
    /// The file open as @p fd (named @p path in the error).
    static FileStamp of(int fd, const std::string& path);
};

/// @brief Requires @p path to be the version @p first stamps.
/// @throw InputError "PATH: file changed while it was being read: ..." naming what changed.
void requireUnchangedFile(const std::string& path, const FileStamp& first);

/// @brief What kind of file a stat mode is, for messages: "a directory", "a FIFO", ...
const char* fileKindName(mode_t mode);

/// @brief The inputs of one job (a bake, a conversion): inputs are recorded only while a scope
/// is alive, and forgotten when the outermost one ends, so that a process running several jobs
/// (the tests, a benchmark) may write in one job what it read in an earlier one.
class InputScope {
public:
    InputScope();
    ~InputScope();
    InputScope(const InputScope&) = delete;
    InputScope& operator=(const InputScope&) = delete;
};

/// @brief The path of the input recorded with this device and inode in the current scope, if any.
std::optional<std::string> recordedInput(dev_t device, ino_t inode);

/// @brief A 64-bit fingerprint of the inputs recorded so far in the current scope: their sizes
/// and modification times, in a sorted order, not their paths (a shard and its merge may name
/// the same files differently). Partial files carry it, so that a checkpoint or a shard made
/// before a geometry file changed is refused, not merged. 0 outside a scope.
uint64_t recordedInputsFingerprint();

}  // namespace penumbra
