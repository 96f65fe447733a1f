#include "stream/RegularFile.h"

#include "stream/Error.h"

#include <cerrno>
#include <cstring>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace penumbra {

RegularFile::RegularFile(const std::string& path) : path_(path) {
    // O_NONBLOCK: opening a FIFO must not wait for a writer; it is refused just below.
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd_ < 0) fail(path, "cannot open: {}", std::strerror(errno));
    struct stat st {};
    if (::fstat(fd_, &st) != 0) {
        const int error = errno;
        ::close(fd_);
        fail(path, "cannot stat: {}", std::strerror(error));
    }
    if (!S_ISREG(st.st_mode)) {
        ::close(fd_);
        fail(path, "not a regular file");
    }
    size_ = uint64_t(st.st_size);
}

RegularFile::~RegularFile() { ::close(fd_); }

void RegularFile::read(void* out, size_t bytes, uint64_t offset) const {
    auto* p = static_cast<char*>(out);
    while (bytes > 0) {
        ssize_t got = ::pread(fd_, p, bytes, off_t(offset));
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) fail(path_, "read error: {}", std::strerror(errno));
        if (got == 0) fail(path_, "file shrank while it was being read");
        p += got, offset += uint64_t(got), bytes -= size_t(got);
    }
}

}  // namespace penumbra
