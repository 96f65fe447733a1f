#pragma once
/// @file FileCommands.h
/// @brief The commands that read files and print or write one result: `compare`, `info`,
/// `convert` and `vdb-slice`. Each prints its result to stdout, where a failed write is an error.

#include "Compare.h"

#include <CLI/CLI.hpp>

#include <optional>
#include <string>

namespace penumbra {

/// Options of every file command, and which one was chosen.
struct FileCommands {
    CompareOptions compare;
    std::string infoPath;
    std::string convertIn, convertOut;
    bool infoQuiet = false, convertQuiet = false;  ///< no progress on stderr
    std::string sliceIn, sliceOut, sliceGrid = "visibility", sliceAxis = "y";
    double sliceAt = 0;
    CLI::App *compareCommand = nullptr, *infoCommand = nullptr, *convertCommand = nullptr, *sliceCommand = nullptr;
};

/// @brief Adds compare, info, convert and vdb-slice to @p app, parsing into @p commands.
void addFileCommands(CLI::App& app, FileCommands& commands);

/// @brief Runs the chosen file command, if one was chosen.
/// @param context receives the command's main input, for errors a library throws.
/// @return the exit code (compare: 3 when the dumps differ), or nullopt when none was chosen.
/// @throw InputError naming the file.
std::optional<int> runFileCommand(const FileCommands& commands, std::string& context);

}  // namespace penumbra
