#include "stream/Diagnostics.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>

namespace penumbra {
namespace {

/// Writes everything to descriptor 2, giving up silently on an error: a diagnostic that cannot
/// be shown is lost, and nothing else happens.
void writeStderr(const char* data, size_t size) noexcept {
    while (size > 0) {
        ssize_t n = ::write(STDERR_FILENO, data, size);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return;
        data += n;
        size -= size_t(n);
    }
}

ssize_t cookieWrite(void*, const char* data, size_t size) {
    writeStderr(data, size);
    return ssize_t(size);  // always "written": stdio then never sets an error that fmt would throw for
}

/// Gives a closed standard descriptor /dev/null, so the next open() cannot land on it.
void reopenIfClosed(int fd) {
    if (::fcntl(fd, F_GETFD) != -1 || errno != EBADF) return;
    int opened = ::open("/dev/null", fd == STDIN_FILENO ? O_RDONLY : O_WRONLY);
    if (opened >= 0 && opened != fd) {
        ::dup2(opened, fd);
        ::close(opened);
    }
}

}  // namespace

void makeStandardStreamsSafe() {
    for (int fd : {STDIN_FILENO, STDOUT_FILENO, STDERR_FILENO}) reopenIfClosed(fd);
    std::signal(SIGPIPE, SIG_IGN);
    static bool replaced = false;
    if (replaced) return;
    cookie_io_functions_t functions{};
    functions.write = &cookieWrite;
    if (std::FILE* safe = ::fopencookie(nullptr, "w", functions)) {
        std::setvbuf(safe, nullptr, _IONBF, 0);  // as stderr: every message goes out at once
        stderr = safe;
        replaced = true;
    }
}

void printDiagnostic(std::string_view text) noexcept { writeStderr(text.data(), text.size()); }

}  // namespace penumbra
