#include "bake/BakeOutputs.h"

#include "bake/kinds/ReceiverKind.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/PathText.h"
#include "stream/util/SafePath.h"

#include <sys/stat.h>

#include <filesystem>
#include <vector>

namespace fs = std::filesystem;

namespace penumbra {
namespace {

/// Every string under a "path" key in @p j (scatter sources nest entries), resolved against
/// @p base. The JSON is depth-limited when read (JsonText.h), so the recursion is bounded.
void collectPaths(const nlohmann::json& j, const fs::path& base, std::vector<std::string>& out) {
    if (j.is_object()) {
        for (auto it = j.begin(); it != j.end(); ++it) {
            if (it.key() == "path" && it->is_string()) out.push_back((base / it->get<std::string>()).lexically_normal().string());
            else collectPaths(*it, base, out);
        }
    } else if (j.is_array()) {
        for (const nlohmann::json& e : j) collectPaths(e, base, out);
    }
}

/// The files a bake of @p scene reads.
std::vector<std::string> sceneInputs(const SceneDesc& scene) {
    std::vector<std::string> inputs{scene.file};
    for (const GeometryDesc& g : scene.geometry) collectPaths(g.params, scene.baseDir, inputs);
    collectPaths(scene.receivers, scene.baseDir, inputs);
    return inputs;
}

/// Refuses @p output when it is the same file as one of @p inputs (device and inode).
void refuseInputs(const std::string& output, const std::vector<std::string>& inputs) {
    struct stat out {};
    if (::stat(output.c_str(), &out) != 0) return;  // a new file cannot be an input
    for (const std::string& input : inputs) {
        struct stat in {};
        if (::stat(input.c_str(), &in) == 0 && in.st_dev == out.st_dev && in.st_ino == out.st_ino)
            fail(output, "is also an input of this bake ({}); refusing to overwrite it", input);
    }
}

}  // namespace

void requireOutputFolder(const std::string& option, const std::string& path) {
    const fs::path parent = fs::path(path).parent_path();
    std::error_code ec;
    if (parent.empty() || fs::is_directory(parent, ec)) return;
    if (fs::exists(parent, ec)) fail(option, "\"{}\": {} is not a folder", path, parent.string());
    fail(option, "\"{}\": the folder {} does not exist (create it first)", path, parent.string());
}

void checkOutputAgainstInputs(const SceneDesc& scene, const std::string& output) {
    checkOutputPath(output);
    refuseInputs(output, sceneInputs(scene));
}

void checkBakeOutputs(const SceneDesc& scene, const std::string& statsPath, const std::string& dumpDir,
                      const std::string& visibilityPath, const std::vector<std::string>& directories,
                      const std::vector<std::string>& kindFiles) {
    checkSceneOutput(scene);
    std::vector<std::string> outputs{scene.output};
    // The files the kind writes beside the output (a camera's PNG) too, so that a dump folder or
    // a directory standing at their name stops the bake now, not after the cast.
    for (std::string& derived : receiverKindDerivedOutputs(scene)) outputs.push_back(std::move(derived));
    outputs.insert(outputs.end(), kindFiles.begin(), kindFiles.end());
    if (!statsPath.empty()) outputs.push_back(statsPath);
    if (!visibilityPath.empty()) outputs.push_back(visibilityPath);
    std::vector<bool> folder(outputs.size(), false);  // folders of their own: not another output's name
    for (const std::string& d : directories)
        if (!d.empty()) outputs.push_back(d), folder.push_back(true);
    if (!dumpDir.empty()) {
        outputs.push_back(dumpDir), folder.push_back(true);
        for (const char* name : {"receivers.npy", "samples.npy", "masks.npy", "rule.json"})
            outputs.push_back((fs::path(dumpDir) / name).string()), folder.push_back(false);
    }
    const std::vector<std::string> inputs = sceneInputs(scene);
    std::vector<std::string> names;  // comparablePath() of each output
    for (size_t i = 0; i < outputs.size(); ++i) {
        names.push_back(comparablePath(outputs[i]));
        for (size_t j = 0; j < i; ++j)
            if (names[i] == names[j]) fail(outputs[i], "is named for two outputs of this bake; give each its own file");
        if (!folder[i]) checkOutputPath(outputs[i]), refuseInputs(outputs[i], inputs);
        else checkOutputFolder(outputs[i]);  // before the work, not when the first shard file is written
    }
    // A folder made for one output (--stats c.png/s.json) at the name of another that is a file
    // (the camera's c.png) would be found only when the files are put in place, after the cast.
    // (Equal names were refused above.)
    for (size_t i = 0; i < outputs.size(); ++i)
        for (size_t j = 0; j < outputs.size(); ++j)
            if (i != j && !folder[j] && isInside(names[i], names[j]))
                fail(outputs[i], "is inside {}, which is an output file of this bake; give each its own name", outputs[j]);
}

}  // namespace penumbra
