#pragma once
/// @file Plugins.h
/// @brief Parts of penumbra that are loaded only when a bake needs them, as shared objects beside
/// the executable (`penumbra_NAME.so`). The volume receivers are one: OpenVDB and what it brings
/// (boost, log4cplus, whose start-up spawns a thread) map about 60 MB and must not count against
/// every bake's address space (`prlimit --as`), nor abort a bake that never writes a VDB.
///
/// A plugin registers itself when loaded (a static registration object, as the built-in parts
/// do); programs that link it in (the tests, the Python module) never load the file.

#include <string>
#include <vector>

namespace penumbra {

/// @brief Loads `penumbra_NAME.so` once per process, from PENUMBRA_PLUGIN_DIR, else beside the
/// executable, else the installed plugin folder (lib/penumbra relative to bin/).
/// @return true when it is loaded (now or before), false when no such plugin exists.
/// @throw InputError naming the file when it exists but cannot be loaded (a missing library, or
/// too little address space left to map it).
bool loadPlugin(const std::string& name);

/// @brief The plugins this build makes (CMakeLists.txt's `penumbra_plugins`: "volume"), so that a
/// missing one is named as missing rather than as an unknown name.
bool isBuiltPlugin(const std::string& name);

/// @brief The names of the plugins this build makes, for lists of what a name may be.
std::vector<std::string> builtPlugins();

/// @brief Where loadPlugin() looks, for messages: "PENUMBRA_PLUGIN_DIR, /usr/bin and /usr/lib/penumbra".
std::string pluginSearchPlaces();

}  // namespace penumbra
