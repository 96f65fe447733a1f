#include "stream/util/Plugins.h"

#include "stream/util/Error.h"
#include "stream/util/Memory.h"

#include <dlfcn.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <vector>

#ifndef PENUMBRA_PLUGIN_RELDIR
#define PENUMBRA_PLUGIN_RELDIR "../lib/penumbra"
#endif
#ifndef PENUMBRA_BUILT_PLUGINS  // comma-separated, from CMakeLists.txt's penumbra_plugins
#define PENUMBRA_BUILT_PLUGINS ""
#endif

namespace penumbra {
namespace fs = std::filesystem;
namespace {

/// Address space a plugin's libraries may need to map; checked first, so that a capped process
/// gets a sentence instead of a loader abort (a library that starts a thread while loading
/// terminates the process when the thread's stack cannot be mapped). OpenVDB and its libraries
/// map 58 MiB; log4cplus starts a thread as it loads, whose stack and malloc arena take the rest
/// (at 142-150 MiB, 80 MiB of headroom passed and the load aborted).
constexpr size_t kPluginHeadroom = size_t(104) << 20;

std::vector<fs::path> pluginDirs() {
    std::vector<fs::path> dirs;
    if (const char* dir = std::getenv("PENUMBRA_PLUGIN_DIR"); dir && *dir) dirs.emplace_back(dir);
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) dirs.push_back(exe.parent_path()), dirs.push_back((exe.parent_path() / PENUMBRA_PLUGIN_RELDIR).lexically_normal());
    return dirs;
}

std::string pluginPath(const std::string& name) {
    const std::string file = "penumbra_" + name + ".so";
    std::error_code ec;
    for (const fs::path& d : pluginDirs())
        if (fs::is_regular_file(d / file, ec)) return (d / file).lexically_normal().string();
    return {};
}

}  // namespace

std::vector<std::string> builtPlugins() {
    std::vector<std::string> names;
    const std::string built = PENUMBRA_BUILT_PLUGINS;
    for (size_t at = 0; at <= built.size();) {
        const size_t comma = std::min(built.find(',', at), built.size());
        if (comma > at) names.push_back(built.substr(at, comma - at));
        at = comma + 1;
    }
    return names;
}

bool isBuiltPlugin(const std::string& name) {
    const std::vector<std::string> names = builtPlugins();  // whole entries only
    return std::find(names.begin(), names.end(), name) != names.end();
}

std::string pluginSearchPlaces() {
    std::string places;
    const std::vector<fs::path> dirs = pluginDirs();
    for (size_t i = 0; i < dirs.size(); ++i)
        places += (i == 0 ? "" : i + 1 == dirs.size() ? " and " : ", ") + dirs[i].string();
    return places.empty() ? "nowhere (/proc/self/exe is unreadable)" : places;
}

bool loadPlugin(const std::string& name) {
    static std::mutex mutex;
    static std::map<std::string, bool> loaded;
    std::lock_guard lock(mutex);
    if (auto it = loaded.find(name); it != loaded.end()) return it->second;
    const std::string path = pluginPath(name);
    if (path.empty()) return loaded[name] = false;
    if (!addressSpaceAvailable(kPluginHeadroom))
        fail(path, "cannot load: it needs at least {} MiB more address space than the limit (prlimit --as, ulimit -v) leaves",
             kPluginHeadroom >> 20);
    // RTLD_GLOBAL: the plugin's libraries serve later plugins too; symbols of penumbra itself
    // come from the executable, which exports them.
    if (!::dlopen(path.c_str(), RTLD_NOW | RTLD_GLOBAL)) {
        const char* why = ::dlerror();
        fail(path, "cannot load: {}", why ? why : "unknown error");
    }
    return loaded[name] = true;
}

}  // namespace penumbra
