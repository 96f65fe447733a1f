#include "stream/util/StopRequest.h"

#include "stream/util/TempRegistry.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <ctime>

namespace penumbra {
namespace {

std::atomic<int> g_stop{0};
struct sigaction g_previous {};  ///< SIGTERM's handler before the deferral, put back after it

extern "C" void deferredTerminationHandler(int sig) {
    if (g_stop.exchange(1) == 0) return;  // the first SIGTERM: the bake stops at its next safe point
    // The second: at once, as without checkpoints. Only async-signal-safe calls.
    const int savedErrno = errno;
    removeRegisteredTempFiles();
    ::signal(sig, SIG_DFL);
    ::raise(sig);  // blocked while the handler runs: delivered, and fatal, when it returns
    errno = savedErrno;
}

/// The value of environment variable @p name, or "". Callers keep it in a function-local static:
/// the hooks are polled once per chunk, and statics are initialised once, thread-safely.
std::string envText(const char* name) {
    const char* v = std::getenv(name);
    return v ? v : "";
}

void touch(const std::string& path) noexcept {
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
    if (fd >= 0) ::close(fd);
}

void napBriefly() noexcept {
    const timespec tenMs{0, 10'000'000};
    ::nanosleep(&tenMs, nullptr);
}

}  // namespace

DeferredTermination::DeferredTermination() {
    struct sigaction old {};
    if (::sigaction(SIGTERM, nullptr, &old) != 0 || old.sa_handler == SIG_IGN) return;  // nohup and the like
    g_stop = 0;
    struct sigaction action {};
    action.sa_handler = deferredTerminationHandler;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESTART;  // reads and writes in progress go on; the flag is polled
    installed_ = ::sigaction(SIGTERM, &action, &g_previous) == 0;
}

DeferredTermination::~DeferredTermination() {
    if (installed_) ::sigaction(SIGTERM, &g_previous, nullptr);
}

bool stopRequested() noexcept { return g_stop.load(std::memory_order_relaxed) != 0; }

void throwIfStopRequested(std::string_view phase) {
    if (!stopRequested()) return;
    static const std::string hold = envText("PENUMBRA_TEST_HOLD_AFTER_STOP");
    if (!hold.empty()) {
        touch(hold);
        for (;;) ::pause();  // until the second signal ends the process
    }
    throw StopRequested("stopped by SIGTERM during the " + std::string(phase));
}

void testPoint(std::string_view point) noexcept {
    static const std::string killAt = envText("PENUMBRA_TEST_KILL_AT"), pauseAt = envText("PENUMBRA_TEST_PAUSE_AT"),
                             pauseFile = envText("PENUMBRA_TEST_PAUSE_FILE");
    if (killAt == point) ::raise(SIGKILL);
    if (pauseAt != point) return;
    touch(pauseFile);
    while (!stopRequested()) napBriefly();
}

}  // namespace penumbra
