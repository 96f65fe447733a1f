#include "bake/kinds/ReceiverKind.h"
#include "stream/util/PathText.h"

#include "bake/Scene.h"
#include "receivers/PointReceivers.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/Npy.h"
#include "stream/util/Plugins.h"
#include "stream/util/SafePath.h"

#include <fmt/ranges.h>

#include <algorithm>
#include <map>
#include <mutex>
#include <optional>

namespace penumbra {
namespace {

std::mutex registryMutex;
/// A registered kind: its factory, the extension of the file it writes, and the files it writes
/// beside it.
struct KindEntry {
    ReceiverKindFactory factory;
    std::string extension;
    DerivedOutputs derived = nullptr;
};

std::map<std::string, KindEntry>& registry() {
    static std::map<std::string, KindEntry> kinds;
    return kinds;
}

/// The kind @p type, loading its plugin (penumbra_TYPE.so, stream/util/Plugins.h) when no kind of
/// that name is built in; nullopt when there is none.
std::optional<KindEntry> findKind(const std::string& type) {
    for (int attempt = 0; attempt < 2; ++attempt) {
        {
            std::lock_guard lock(registryMutex);
            if (auto it = registry().find(type); it != registry().end()) return it->second;
        }
        if (attempt == 0 && !loadPlugin(type)) break;  // the plugin registers its kind as it loads
    }
    return std::nullopt;
}

/// The kind the "receivers" object's "type" names; nullopt when it names none (or no known one).
std::optional<KindEntry> kindOf(const nlohmann::json& receivers) {
    if (!receivers.is_object() || !receivers.contains("type") || !receivers["type"].is_string()) return std::nullopt;
    return findKind(receivers["type"].get<std::string>());
}

/// Point receivers from a file; a .npy of visible fractions.
class PointsKind final : public ReceiverKind {
public:
    explicit PointsKind(std::string path) : path_(std::move(path)) {}
    std::optional<uint64_t> receiverBound() const override { return pointReceiverBound(path_); }
    ReceiverSet receivers() override { return loadPointReceivers(path_); }
    void write(const OutputContext& c) override {
        uint64_t shape[1] = {c.results.visibility.size()};
        ensureParentDirectory(c.output);
        writeNpy(c.output, "<f4", shape, c.results.visibility.data(), c.results.visibility.size() * sizeof(float));
        // Any name is written (scenes name "x.exr" for points bakes), but an .npy under another
        // extension is worth a word, once the bake has succeeded up to here.
        if (lowercaseExtension(c.output) != ".npy" && !AtomicFile::writtenInto(c.output))
            printWarning("{}: \"{}\" holds a NumPy .npy array (points receivers write one, whatever the extension)",
                         c.scene.outputFromScene ? c.scene.file + ": output" : "--output", c.output);
    }

private:
    std::string path_;
};

}  // namespace

std::string resolveScenePath(const std::filesystem::path& base, const std::string& p, const std::string& where) {
    return containedPath(base, p, where.empty() ? p : where);
}

void requireOutputExtension(const SceneDesc& scene, const std::vector<std::string>& extensions, const std::string& kind,
                            bool oneFile) {
    const std::string ext = lowercaseExtension(scene.output);
    for (const std::string& e : extensions)
        if (ext == e) return;
    if (oneFile && AtomicFile::writtenInto(scene.output)) return;
    const std::string where = scene.outputFromScene ? scene.file + ": output" : "--output";
    fail(where, "\"{}\": {} receivers write {} files; name the output with that extension", scene.output, kind,
         fmt::format("{}", fmt::join(extensions, " or ")));
}

void registerReceiverKind(const std::string& type, ReceiverKindFactory factory, std::string outputExtension,
                          DerivedOutputs derived) {
    std::lock_guard lock(registryMutex);
    registry()[type] = KindEntry{std::move(factory), std::move(outputExtension), derived};
}

std::vector<std::string> receiverKindDerivedOutputs(const SceneDesc& scene) {
    const std::optional<KindEntry> kind = kindOf(scene.receivers);
    if (!kind || !kind->derived) return {};
    std::vector<std::string> paths = kind->derived(scene.output);
    // `-o x.png` of a camera: the kind refuses the output's extension, a clearer error.
    std::erase(paths, scene.output);
    return paths;
}

std::string receiverKindExtension(const nlohmann::json& receivers) {
    const std::optional<KindEntry> kind = kindOf(receivers);
    return kind ? kind->extension : ".exr";
}

namespace {
const ReceiverKindRegistration kPoints{"points", [](const JsonParams& j, const SceneDesc& scene, KindUse use) {
    std::string path = resolveScenePath(scene.baseDir, j.string("path"), j.where("path"));
    return use == KindUse::Validate ? nullptr : std::make_unique<PointsKind>(std::move(path));
}, ".npy"};

std::unique_ptr<ReceiverKind> makeKind(const nlohmann::json& receivers, const SceneDesc& scene, KindUse use) {
    JsonParams j(receivers, scene.file, "receivers");
    const std::string type = j.string("type");
    const std::optional<KindEntry> entry = findKind(type);
    if (!entry && isBuiltPlugin(type))
        fail(j.where("type"), "\"{}\" receivers need the plugin penumbra_{}.so, which is not in {} (copy it with the "
             "executable, or set PENUMBRA_PLUGIN_DIR)", type, type, pluginSearchPlaces());
    if (!entry) {
        std::lock_guard lock(registryMutex);
        std::vector<std::string> known;
        for (const auto& e : registry()) known.push_back(e.first);
        for (const std::string& plugin : builtPlugins())  // "volume", before its plugin is loaded
            if (std::find(known.begin(), known.end(), plugin) == known.end()) known.push_back(plugin);
        std::sort(known.begin(), known.end());
        fail(j.where("type"), "unknown receiver type \"{}\" (known: {})", type, fmt::join(known, ", "));
    }
    std::unique_ptr<ReceiverKind> kind = entry->factory(j, scene, use);
    j.finish();
    return kind;
}

}  // namespace

std::unique_ptr<ReceiverKind> makeReceiverKind(const nlohmann::json& receivers, const SceneDesc& scene) {
    return makeKind(receivers, scene, KindUse::Bake);
}

void validateReceiverKind(const nlohmann::json& receivers, const SceneDesc& scene) {
    makeKind(receivers, scene, KindUse::Validate);
}

}  // namespace penumbra
