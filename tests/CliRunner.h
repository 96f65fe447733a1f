#pragma once
// Runs the real `penumbra` binary in a shell and captures its exit code and output, for tests of
// the command line (error messages, exit codes, files written).

#include "TestSupport.h"

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

/// Runs `penumbra ARGS` (ARGS is shell text) with an optional prefix such as "prlimit ...".
inline RunResult runPenumbra(const std::string& args, const std::string& prefix = "") {
    ScratchDir io("run");
    std::string cmd = prefix + " " + PENUMBRA_BINARY + " " + args + " >" + (io / "out") + " 2>" + (io / "err");
    int status = std::system(cmd.c_str());
    RunResult r;
    r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    r.out = slurp(io / "out");
    r.err = slurp(io / "err");
    return r;
}

inline int lineCount(const std::string& s) {
    int n = 0;
    for (char c : s) n += c == '\n';
    return n;
}

}  // namespace penumbra::test
