#include "bake/LibraryErrors.h"

#include <Iex.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <mutex>
#include <vector>

namespace penumbra {
namespace {

std::mutex typesMutex;
std::vector<bool (*)(const std::exception&)>& registeredTypes() {
    static std::vector<bool (*)(const std::exception&)> types;
    return types;
}

bool isRegisteredType(const std::exception& e) {
    std::lock_guard lock(typesMutex);
    for (auto* is : registeredTypes())
        if (is(e)) return true;
    return false;
}

}  // namespace

void registerLibraryErrorType(bool (*isLibraryError)(const std::exception&)) {
    std::lock_guard lock(typesMutex);
    registeredTypes().push_back(isLibraryError);
}

std::optional<std::string> libraryErrorMessage(const std::exception& e) {
    std::string what;
    if (const auto* fs = dynamic_cast<const std::filesystem::filesystem_error*>(&e)) {
        what = fs->path1().empty() ? fs->code().message() : fs->path1().string() + ": " + fs->code().message();
    } else if (dynamic_cast<const nlohmann::json::exception*>(&e) || dynamic_cast<const Iex::BaseExc*>(&e) ||
               isRegisteredType(e)) {
        what = e.what();
    } else {
        return std::nullopt;
    }
    // One line: libraries sometimes append details on further lines.
    what = what.substr(0, what.find('\n'));
    return what.empty() ? std::string("a library reported an error without a message") : what;
}

}  // namespace penumbra
