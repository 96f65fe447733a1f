#pragma once
// The Khronos glTF validator (npm package gltf-validator, installed by setup.sh under
// build/npm), run through tools/validate-gltf.mjs; tests skip validation when it is missing.

#include "TestSupport.h"

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace penumbra::test {

/// Whether node and the npm package are there; @p dir gets the package's --prefix.
inline bool validatorAvailable(std::string& dir) {
    dir = (std::filesystem::path(PENUMBRA_BINARY).parent_path() / "npm").string();
    if (const char* env = std::getenv("PENUMBRA_GLTF_VALIDATOR_DIR")) dir = env;
    return std::filesystem::exists(std::filesystem::path(dir) / "node_modules/gltf-validator") &&
           std::system("node --version >/dev/null 2>&1") == 0;
}

/// The validator's exit code for @p file (0 valid, 1 errors), with its report in @p log.
inline int validateGltf(const std::string& file, const std::string& dir, std::string& log) {
    ScratchDir io("validate");
    std::string cmd = "node " + std::string(PENUMBRA_SOURCE_DIR) + "/tools/validate-gltf.mjs '" + file + "' '" + dir +
                      "' >" + (io / "log") + " 2>&1";
    int status = std::system(cmd.c_str());
    log = slurp(io / "log");
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace penumbra::test
