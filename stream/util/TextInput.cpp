#include "stream/util/TextInput.h"

#include "stream/util/Error.h"
#include "stream/util/InputFile.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <memory>
#include <system_error>
#include <vector>

namespace penumbra {
namespace {

constexpr size_t kSniffBytes = 64 * 1024;

}  // namespace

void checkTextFile(const std::string& path, const char* format) {
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(openInputStream(path), &std::fclose);
    std::vector<unsigned char> head(kSniffBytes);
    const size_t n = std::fread(head.data(), 1, head.size(), file.get());
    if (std::ferror(file.get())) fail(path, "read error: {}", std::strerror(errno));
    if (n >= 2 && ((head[0] == 0xFF && head[1] == 0xFE) || (head[0] == 0xFE && head[1] == 0xFF)))
        fail(path, "is UTF-16 text; {} files are ASCII or UTF-8", format);
    if (const void* nul = std::memchr(head.data(), 0, n))
        fail(path, "is binary, not {} text (a NUL byte at offset {})", format, static_cast<const unsigned char*>(nul) - head.data());
}

void checkLineReadEnded(std::FILE* file, const std::string& where, int readErrno) {
    if (std::feof(file)) return;
    const int err = readErrno != 0 ? readErrno : EIO;
    fail(where, "read error: {}", std::error_code(err, std::generic_category()).message());
}

void warnIfNoFaces(const std::string& path, uint64_t triangles) {
    if (triangles > 0) return;
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) return;
    // An empty file too: it is most often one whose export or copy failed.
    if (st.st_size == 0) printWarning("{}: is empty (0 triangles)", path);
    else printWarning("{}: no face line was understood (0 triangles)", path);
}

}  // namespace penumbra
