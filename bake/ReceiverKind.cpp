#include "bake/ReceiverKind.h"

#include "bake/CameraOutput.h"
#include "bake/Scene.h"
#include "receivers/CameraReceivers.h"
#include "receivers/PointReceivers.h"
#include "stream/AtomicFile.h"
#include "stream/Error.h"
#include "stream/Npy.h"

#include <fmt/ranges.h>

#include <map>
#include <optional>
#include <mutex>

namespace penumbra {
namespace {

std::mutex registryMutex;
std::map<std::string, ReceiverKindFactory>& registry() {
    static std::map<std::string, ReceiverKindFactory> kinds;
    return kinds;
}

/// Camera receivers: a z-buffer pass over the scene stream; EXR + PNG preview.
class CameraKind final : public ReceiverKind {
public:
    explicit CameraKind(const CameraDesc& camera) : camera_(camera) { validateCamera(camera); }
    uint64_t scanBytes() const override {
        return uint64_t(camera_.width) * camera_.height * CameraRasterizer::kBytesPerPixel;
    }
    void scan(std::span<const Triangle> chunk) override { raster().add(chunk); }
    ReceiverSet receivers() override { return raster().finish(); }
    void write(const OutputContext& c) override { writeCameraOutputs(c.scene, c.receivers, c.samples, c.results, c.output); }

private:
    // The z-buffer is allocated when the scan starts, not when the scene is validated.
    CameraRasterizer& raster() {
        if (!raster_) raster_.emplace(camera_);
        return *raster_;
    }
    CameraDesc camera_;
    std::optional<CameraRasterizer> raster_;
};

/// Point receivers from a file; a .npy of visible fractions.
class PointsKind final : public ReceiverKind {
public:
    explicit PointsKind(std::string path) : path_(std::move(path)) {}
    ReceiverSet receivers() override { return loadPointReceivers(path_); }
    void write(const OutputContext& c) override {
        uint64_t shape[1] = {c.results.visibility.size()};
        ensureParentDirectory(c.output);
        writeNpy(c.output, "<f4", shape, c.results.visibility.data(), c.results.visibility.size() * sizeof(float));
    }

private:
    std::string path_;
};

}  // namespace

std::string resolveScenePath(const std::filesystem::path& base, const std::string& p) {
    std::filesystem::path path(p);
    return (path.is_absolute() ? path : base / path).lexically_normal().string();
}

void registerReceiverKind(const std::string& type, ReceiverKindFactory factory) {
    std::lock_guard lock(registryMutex);
    registry()[type] = std::move(factory);
}

void registerBuiltinReceiverKinds() {
    static std::once_flag once;
    std::call_once(once, [] {
        registerReceiverKind("camera", [](const JsonParams& j, const SceneDesc&) {
            CameraDesc c;
            c.where = j.where();
            c.eye = j.vec3("eye"), c.target = j.vec3("target"), c.up = j.vec3("up", c.up);
            c.fovDeg = j.number("fov_deg", c.fovDeg);
            c.width = int(j.integer("width", c.width, 1, 65536));
            c.height = int(j.integer("height", c.height, 1, 65536));
            return std::make_unique<CameraKind>(c);
        });
        registerReceiverKind("points", [](const JsonParams& j, const SceneDesc& scene) {
            return std::make_unique<PointsKind>(resolveScenePath(scene.baseDir, j.string("path")));
        });
    });
}

std::unique_ptr<ReceiverKind> makeReceiverKind(const nlohmann::json& receivers, const SceneDesc& scene) {
    registerBuiltinReceiverKinds();
    JsonParams j(receivers, scene.file, "receivers");
    const std::string type = j.string("type");
    ReceiverKindFactory factory;
    {
        std::lock_guard lock(registryMutex);
        auto it = registry().find(type);
        if (it == registry().end()) {
            std::vector<std::string> known;
            for (const auto& entry : registry()) known.push_back(entry.first);
            fail(j.where("type"), "unknown receiver type \"{}\" (known: {})", type, fmt::join(known, ", "));
        }
        factory = it->second;
    }
    std::unique_ptr<ReceiverKind> kind = factory(j, scene);
    j.finish();
    return kind;
}

}  // namespace penumbra
