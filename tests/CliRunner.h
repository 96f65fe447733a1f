#pragma once
// Runs the real `penumbra` binary in a shell and captures its exit code and output, for tests of
// the command line (error messages, exit codes, files written).

#include "TestSupport.h"

#include <nlohmann/json.hpp>

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

/// Runs shell text @p command (which names the binary as PENUMBRA_BINARY itself) and returns its
/// exit code, 128 + the signal when killed; for tests that redirect stdout and stderr their own way.
inline int runShell(const std::string& command) {
    int status = std::system(command.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

/// A JSON array of the one entry @p e: `{x}` of a single element means x itself to some compilers
/// (clang) and [x] to others.
inline nlohmann::json listOf(nlohmann::json e) {
    nlohmann::json list = nlohmann::json::array();
    list.push_back(std::move(e));
    return list;
}

/// How many times @p what occurs in @p text (overlapping occurrences counted).
inline size_t occurrences(const std::string& text, const std::string& what) {
    size_t n = 0;
    for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
    return n;
}

inline int lineCount(const std::string& s) {
    int n = 0;
    for (char c : s) n += c == '\n';
    return n;
}

/// Exit 1 and exactly one line on stderr, "penumbra: error: ..." containing @p fragment.
inline void requireCleanError(const RunResult& r, const std::string& fragment) {
    INFO("stderr: " << r.err);
    CHECK(r.exitCode == 1);
    CHECK(lineCount(r.err) == 1);
    CHECK_THAT(r.err, Catch::StartsWith("penumbra: error: ") && Catch::Contains(fragment));
}

/// True when a temporary output (".tmp" in its name) is left anywhere under @p dir.
inline bool hasTempFiles(const std::filesystem::path& dir) {
    if (!std::filesystem::exists(dir)) return false;
    for (const auto& e : std::filesystem::recursive_directory_iterator(dir))
        if (e.path().filename().string().find(".tmp") != std::string::npos) return true;
    return false;
}

}  // namespace penumbra::test
