#pragma once
/// @file StopRequest.h
/// @brief A graceful stop on SIGTERM, for bakes that keep checkpoints (`--checkpoint`), and the
/// deterministic kill and pause points the tests of resume use.
///
/// Slurm sends SIGTERM some time (KillWait) before SIGKILL at a job's time limit. A bake with
/// checkpoints can use that time: while a DeferredTermination lives, the first SIGTERM only sets a
/// flag, which the bake polls at safe points (between chunks of the scan, the bucket pass and the
/// cast); there it writes what it has and unwinds with StopRequested, which the CLI turns into
/// exit 143 with one line. A second SIGTERM, or any SIGINT, ends the process at once, as without
/// checkpoints (the cleanup handlers of TempRegistry.h: registered temporaries removed, then the
/// signal's default action).

#include <stdexcept>
#include <string>
#include <string_view>

namespace penumbra {

/// @brief The exception a bake unwinds with after SIGTERM; what() is the line to print.
class StopRequested : public std::runtime_error {
public:
    explicit StopRequested(const std::string& message) : std::runtime_error(message) {}
};

/// @brief The exit code of a bake stopped by SIGTERM (128 + 15, what a shell shows for it).
inline constexpr int kStoppedExitCode = 143;

/// @brief While alive, SIGTERM asks for a stop instead of ending the process (see the file
/// comment). A SIGTERM that the parent set to be ignored stays ignored. Not nestable.
class DeferredTermination {
public:
    DeferredTermination();
    ~DeferredTermination();  ///< puts the immediate handler back
    DeferredTermination(const DeferredTermination&) = delete;
    DeferredTermination& operator=(const DeferredTermination&) = delete;

private:
    bool installed_ = false;
};

/// @brief True once a deferred SIGTERM has arrived.
bool stopRequested() noexcept;

/// @brief Throws StopRequested("stopped by SIGTERM during the @p phase") when a stop was asked
/// for. Cheap (one atomic load): call it once per chunk.
void throwIfStopRequested(std::string_view phase);

/// @brief Test hooks at a named point of a bake (scan, bucket, cast, write), so that the tests of
/// resume act at a known place instead of racing a timer:
///  - `PENUMBRA_TEST_KILL_AT=@p point`: raise(SIGKILL) here, a real kill -9;
///  - `PENUMBRA_TEST_PAUSE_AT=@p point`: create the file named by `PENUMBRA_TEST_PAUSE_FILE`,
///    then wait until a signal asks for a stop (or ends the process), so a test can send a real
///    SIGTERM here.
/// And `PENUMBRA_TEST_HOLD_AFTER_STOP=FILE` answers the first stop request (throwIfStopRequested)
/// by creating FILE and waiting for good, so a test can send the second signal. Nothing happens
/// without these variables.
void testPoint(std::string_view point) noexcept;

}  // namespace penumbra
