#pragma once
// Fixtures shared by the tests: scratch directories, error capture, whole-file reads.

#include "stream/util/Error.h"
#include "stream/util/Npy.h"
#include "stream/util/SafePath.h"

#include <catch2/catch.hpp>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

extern char** environ;

namespace penumbra::test {

/// A file of the shared test data (../shared/data beside the project; see CMakeLists.txt), e.g. "meshes/spot.obj".
inline std::string sharedData(const std::string& rel) { return std::string(PENUMBRA_SHARED_DATA) + "/" + rel; }

/// Lets scenes name files outside their own directory while it lives (`--allow-outside-uris`), for
/// tests whose scenes in a scratch directory use the examples' files.
struct AllowOutsidePaths {
    AllowOutsidePaths() { setOutsidePathsAllowed(true); }
    ~AllowOutsidePaths() { setOutsidePathsAllowed(false); }
    AllowOutsidePaths(const AllowOutsidePaths&) = delete;
    AllowOutsidePaths& operator=(const AllowOutsidePaths&) = delete;
};

/// A fresh directory under the system temp dir (mkdtemp), removed with everything in it.
struct ScratchDir {
    std::filesystem::path path;
    explicit ScratchDir(const std::string& tag = "test") {
        std::string pattern = (std::filesystem::temp_directory_path() / ("penumbra-" + tag + "-XXXXXX")).string();
        REQUIRE(::mkdtemp(pattern.data()) != nullptr);
        path = pattern;
    }
    ~ScratchDir() {
        std::error_code ec;
        std::filesystem::permissions(path, std::filesystem::perms::owner_all, std::filesystem::perm_options::add, ec);
        std::filesystem::remove_all(path, ec);
    }
    ScratchDir(const ScratchDir&) = delete;
    ScratchDir& operator=(const ScratchDir&) = delete;

    std::string file(const std::string& name) const { return (path / name).string(); }
    std::string operator/(const std::string& name) const { return file(name); }
    std::vector<std::string> entries() const {
        std::vector<std::string> names;
        for (const auto& e : std::filesystem::directory_iterator(path)) names.push_back(e.path().filename().string());
        std::sort(names.begin(), names.end());
        return names;
    }
    size_t count() const { return entries().size(); }
    /// Paths of entries whose name starts with @p prefix, recursively.
    std::vector<std::string> find(const std::string& prefix) const {
        std::vector<std::string> out;
        for (const auto& e : std::filesystem::recursive_directory_iterator(path))
            if (e.path().filename().string().rfind(prefix, 0) == 0) out.push_back(e.path().string());
        return out;
    }
};

/// The message of the InputError @p action throws, or a marker when it throws none.
inline std::string errorOf(const std::function<void()>& action) {
    try {
        action();
    } catch (const InputError& e) {
        return e.what();
    }
    return "(no InputError thrown)";
}

/// The whole file as bytes in a string (empty when it cannot be read).
inline std::string slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

/// Re-runs this test binary as a child on the hidden test case(s) @p tag, with @p envName=@p dir
/// in its environment and, if @p fileSizeLimit > 0, that RLIMIT_FSIZE with SIGXFSZ ignored (so an
/// oversize write fails with EFBIG, exactly as under `prlimit --fsize`). For tests of what a
/// process does when killed or when the disk fills. Returns the wait status; the child's stdout
/// and stderr go to @p output.
inline int runSelfAsChild(const std::string& tag, const std::string& envName, const std::string& dir, rlim_t fileSizeLimit,
                          std::string& output) {
    char exe[4096];
    ssize_t len = ::readlink("/proc/self/exe", exe, sizeof exe - 1);
    REQUIRE(len > 0);
    exe[len] = '\0';
    // Built before fork(): only async-signal-safe calls may run between fork and exec, as other
    // threads (TBB, OpenEXR) may hold locks.
    const std::string prefix = envName + "=";
    std::vector<std::string> envStrings;
    for (char** e = environ; *e; ++e)
        if (std::strncmp(*e, prefix.c_str(), prefix.size()) != 0) envStrings.emplace_back(*e);
    envStrings.push_back(prefix + dir);
    std::vector<char*> envp;
    for (auto& s : envStrings) envp.push_back(s.data());
    envp.push_back(nullptr);
    std::string tagArg = tag, colour = "--use-colour", no = "no";
    std::vector<char*> argv = {exe, tagArg.data(), colour.data(), no.data(), nullptr};

    int fds[2];
    REQUIRE(::pipe(fds) == 0);
    pid_t pid = ::fork();
    REQUIRE(pid >= 0);
    if (pid == 0) {
        ::dup2(fds[1], STDOUT_FILENO);
        ::dup2(fds[1], STDERR_FILENO);
        ::close(fds[0]);
        ::close(fds[1]);
        if (fileSizeLimit > 0) {
            ::signal(SIGXFSZ, SIG_IGN);
            struct rlimit limit = {fileSizeLimit, fileSizeLimit};
            if (::setrlimit(RLIMIT_FSIZE, &limit) != 0) ::_exit(120);
        }
        ::execve(exe, argv.data(), envp.data());
        ::_exit(121);
    }
    ::close(fds[1]);
    char buf[4096];
    for (;;) {
        ssize_t got = ::read(fds[0], buf, sizeof buf);
        if (got < 0 && errno == EINTR) continue;
        if (got <= 0) break;
        output.append(buf, size_t(got));
    }
    ::close(fds[0]);
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    return status;
}

/// @brief Writes @p n x @p n receiver points on the floor y = 0, facing up, from (@p first, 0,
/// @p first) in steps of @p step, as a float32 N x 6 .npy at @p path (a points kind's input).
inline void writeFloorPoints(const std::filesystem::path& path, int n, float first, float step) {
    std::vector<float> rows;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) rows.insert(rows.end(), {first + step * float(i), 0.f, first + step * float(j), 0.f, 1.f, 0.f});
    const uint64_t shape[2] = {rows.size() / 6, 6};
    penumbra::writeNpy(path.string(), "<f4", shape, rows.data(), rows.size() * sizeof(float));
}

}  // namespace penumbra::test
