#pragma once
/// @file CliErrors.h
/// @brief How a command ends badly: one line on stderr and the documented exit code (README,
/// "Exit codes"): 1 for errors in the input or the environment, 2 for usage errors, 70 for
/// penumbra's own bugs, 143 for a bake stopped by SIGTERM after writing its checkpoints.

#include <CLI/CLI.hpp>

#include <exception>
#include <string>

namespace penumbra {

/// @brief Prints the one line for an exception that ended a command and returns the exit code.
/// @param context the command's main input, named when the library did not.
int reportError(std::exception_ptr error, const std::string& context);

/// @brief Prints a usage error (an unknown command is named, with the commands there are) and
/// returns 2; --help and --version return 0.
int reportUsageError(CLI::App& app, const CLI::ParseError& e, int argc, char** argv);

}  // namespace penumbra
