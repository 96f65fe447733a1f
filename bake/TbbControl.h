#pragma once
/// @file TbbControl.h
/// @brief A TBB global_control (--threads, the workers' stack size) for the length of a command,
/// kept for the rest of the process under an address-space limit; and the test for a thread that
/// could not start.
///
/// Destroying a control lifts its setting, and TBB then starts the workers that the restored
/// limit allows. Under `prlimit --as` that can fail, and TBB throws from the control's
/// destructor, which aborts the process: `penumbra generate` at 68 MiB finished its output and
/// then ended in `terminate`, and a bake that failed with a one-line "does not fit" error did
/// the same while unwinding. So under an address-space limit the control is never destroyed. A
/// command-line process ends right after; a library caller under such a limit keeps the
/// smallest thread count it asked for (TBB applies the smallest active cap).

#include "stream/util/Error.h"
#include "stream/util/Memory.h"

#include <tbb/global_control.h>

#include <atomic>
#include <cstddef>
#include <exception>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>

namespace penumbra {

class ScopedTbbControl {
public:
    /// @param value the setting; 0 sets nothing
    ScopedTbbControl(tbb::global_control::parameter parameter, size_t value) {
        if (value > 0) control_ = std::make_unique<tbb::global_control>(parameter, value);
    }
    ~ScopedTbbControl() {
        if (addressSpaceLimit() != 0) (void)control_.release();  // deliberately kept: see the file comment
    }
    ScopedTbbControl(const ScopedTbbControl&) = delete;
    ScopedTbbControl& operator=(const ScopedTbbControl&) = delete;

private:
    std::unique_ptr<tbb::global_control> control_;
};

/// @brief Records that a thread could not be started. TBB's workers are then in a state its
/// exit handlers wait on forever (a `generate` retried on one thread finished its output, then
/// hung in exit()), so the command-line tool ends with std::_Exit once this is set
/// (threadStartFailed()).
inline std::atomic<bool>& threadStartFailure() {
    static std::atomic<bool> failed{false};
    return failed;
}
inline void noteThreadStartFailure() { threadStartFailure() = true; }
inline bool threadStartFailed() { return threadStartFailure().load(); }

/// @brief Whether @p e says that a thread could not be started: std::thread's system_error, or the
/// runtime_error TBB throws when pthread_create fails (a command then runs again on one thread).
inline bool isThreadStartFailure(const std::exception& e) {
    if (const auto* se = dynamic_cast<const std::system_error*>(&e))
        return se->code() == std::errc::resource_unavailable_try_again;
    return std::string_view(e.what()).starts_with("pthread_create has failed");
}

/// @brief Whether a command that failed with @p e should run again on one thread, which starts no
/// worker: true for a thread-start failure of a multi-threaded run, which is then noted and warned
/// about. The caller's outputs appear whole or not at all, and their bytes do not depend on the
/// thread count, so the retry loses nothing.
/// @param threads the count that could not start (0: all cores)
/// @param doing what runs again, for the warning ("baking", "generating")
inline bool retryOnOneThread(const std::exception& e, int threads, std::string_view doing) {
    if (threads == 1 || !isThreadStartFailure(e)) return false;
    noteThreadStartFailure();
    printWarning("could not start {} threads ({}); {} on one", threads == 0 ? std::string("all") : std::to_string(threads),
                 e.what(), doing);
    return true;
}

}  // namespace penumbra
