#include "stream/SourceRegistry.h"

#include "stream/util/Error.h"

#include <fmt/ranges.h>

#include <map>
#include <mutex>

namespace penumbra {
namespace {

std::map<std::string, SourceFactory>& registry() {
    static std::map<std::string, SourceFactory> types;
    return types;
}
std::mutex registryMutex;

}  // namespace

void registerSourceType(const std::string& type, SourceFactory factory) {
    std::lock_guard lock(registryMutex);
    registry()[type] = std::move(factory);
}

TriangleSourcePtr openSource(const std::string& type, const SourceRequest& request) {
    SourceFactory factory;
    {
        std::lock_guard lock(registryMutex);
        auto it = registry().find(type);
        if (it == registry().end()) {
            std::vector<std::string> known;
            for (const auto& entry : registry()) known.push_back(entry.first);
            fail(request.where(), "unknown geometry type \"{}\" (known: {})", type, fmt::join(known, ", "));
        }
        factory = it->second;
    }
    return factory(request);
}

}  // namespace penumbra
