#pragma once
// Runs the real `penumbra` binary in a shell and captures its exit code and output, for tests of
// the command line (error messages, exit codes, files written).

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace penumbra::test {

struct RunResult {
    int exitCode = -1;
    std::string out, err;
};

inline std::string readText(const std::filesystem::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

/// A fresh empty directory under the system temp dir, removed when the object dies.
struct TempDir {
    std::filesystem::path path;
    explicit TempDir(const std::string& tag) {
        path = std::filesystem::temp_directory_path() /
               ("penumbra-test-" + tag + "-" + std::to_string(::getpid()) + "-" + std::to_string(std::rand()));
        std::filesystem::remove_all(path);
        std::filesystem::create_directories(path);
    }
    ~TempDir() { std::filesystem::remove_all(path); }
    std::string operator/(const std::string& name) const { return (path / name).string(); }
};

/// Runs `penumbra ARGS` (ARGS is shell text) with an optional prefix such as "prlimit ...".
inline RunResult runPenumbra(const std::string& args, const std::string& prefix = "") {
    static int counter = 0;
    TempDir io("run" + std::to_string(counter++));
    std::string cmd = prefix + " " + PENUMBRA_BINARY + " " + args + " >" + (io / "out") + " 2>" + (io / "err");
    int status = std::system(cmd.c_str());
    RunResult r;
    r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    r.out = readText(io / "out");
    r.err = readText(io / "err");
    return r;
}

inline int lineCount(const std::string& s) {
    int n = 0;
    for (char c : s) n += c == '\n';
    return n;
}

}  // namespace penumbra::test
