#pragma once
/// @file LibraryErrors.h
/// @brief Tells an exception a library threw (JSON, OpenEXR, OpenVDB, the file system) from one
/// of penumbra's own bugs, so that the CLI reports the first as an error in the input (exit 1,
/// naming the file) and only the second as an internal error (exit 70). Readers and writers
/// translate library errors where they call the library; this is the net below them.

#include <exception>
#include <optional>
#include <string>

namespace penumbra {

/// @brief The one-line message of @p e if a library threw it (nlohmann::json::exception,
/// Iex::BaseExc, std::filesystem::filesystem_error, or a type a plugin registered, such as
/// openvdb::Exception), else nullopt.
std::optional<std::string> libraryErrorMessage(const std::exception& e);

/// @brief Makes libraryErrorMessage() recognise the exceptions for which @p isLibraryError is true:
/// a plugin's library (OpenVDB) registers its exception type when the plugin loads.
void registerLibraryErrorType(bool (*isLibraryError)(const std::exception&));

}  // namespace penumbra
