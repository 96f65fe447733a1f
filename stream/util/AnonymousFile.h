#pragma once
/// @file AnonymousFile.h
/// @brief Scratch files nobody can open by name (bucket files, spilled OBJ vertices): the data
/// lives only as long as the descriptor, so the kernel reclaims it however the process ends,
/// SIGKILL and the OOM killer included.

#include <string>

namespace penumbra {

/// @brief Creates an unnamed read-write file in @p dir: O_TMPFILE where the file system has it,
/// else create-then-unlink with the name registered for signal cleanup (AtomicFile.h) in between.
/// @return the descriptor, or -1 with errno set.
int createAnonymousFile(const std::string& dir);

/// @brief Where scratch files go: `--tmp` when set (setScratchDirectory), else the system temp
/// dir ($TMPDIR). @throw InputError when neither can be found.
std::string scratchDirectory();
/// @brief The system temp dir: $TMPDIR, or /tmp when it is unset or empty (as mktemp and Python
/// take it). @throw InputError naming $TMPDIR's value when it is not a usable directory.
std::string systemTempDirectory();
/// @brief Sets the scratch directory for this process (empty: the system temp dir).
void setScratchDirectory(const std::string& dir);

}  // namespace penumbra
