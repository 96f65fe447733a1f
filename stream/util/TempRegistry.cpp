#include "stream/util/TempRegistry.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>

namespace penumbra {

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
        // A folder made for an output that was never put in place: removed only if empty.
        if (::unlink(slot.path) != 0 && errno == EISDIR) ::rmdir(slot.path);
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

/// The cleanup handler, reset to the default action as it runs.
struct sigaction cleanupAction() {
    struct sigaction action {};
    action.sa_handler = cleanupSignalHandler;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESETHAND;
    return action;
}

constexpr int kLibrarySignals[] = {SIGTERM, SIGHUP, SIGQUIT};

}  // namespace

ScopedSignalCleanup::ScopedSignalCleanup() {
    const struct sigaction action = cleanupAction();
    for (int i = 0; i < kSignals; ++i) {
        struct sigaction old {};
        if (::sigaction(kLibrarySignals[i], nullptr, &old) != 0 || old.sa_handler != SIG_DFL) continue;
        installed_[i] = ::sigaction(kLibrarySignals[i], &action, nullptr) == 0;
    }
}

ScopedSignalCleanup::~ScopedSignalCleanup() {
    struct sigaction fallback {};
    fallback.sa_handler = SIG_DFL;
    sigemptyset(&fallback.sa_mask);
    for (int i = 0; i < kSignals; ++i) {
        struct sigaction now {};
        // Only ours is put back: a handler the caller installed meanwhile stays.
        if (installed_[i] && ::sigaction(kLibrarySignals[i], nullptr, &now) == 0 && now.sa_handler == cleanupSignalHandler)
            ::sigaction(kLibrarySignals[i], &fallback, nullptr);
    }
}

void installCleanupSignalHandlers() {
    const struct sigaction action = cleanupAction();
    for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) {
        // Respect an "ignore" inherited from the parent (nohup, background jobs).
        struct sigaction old {};
        if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
        ::sigaction(sig, &action, nullptr);
    }
}

}  // namespace penumbra
