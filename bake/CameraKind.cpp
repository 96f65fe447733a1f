#include "bake/CameraKind.h"

#include "bake/CameraOutput.h"
#include "bake/Scene.h"
#include "bake/SmoothShading.h"
#include "receivers/CameraReceivers.h"

#include <optional>

namespace penumbra {
namespace {

class CameraKind final : public ReceiverKind {
public:
    CameraKind(const CameraDesc& camera, const SceneDesc& scene)
        : camera_(camera), smooth_(scene.smoothShading), lights_(lightDirections(scene.lights)) {
        validateCamera(camera);
    }
    uint64_t scanBytes() const override {
        // The z-buffer (plus the triangle per pixel for smooth shading) and, at the end of the
        // pass, the receiver set made from it (32 bytes per covered pixel).
        uint64_t perPixel = CameraRasterizer::kBytesPerPixel + (smooth_ ? sizeof(std::array<glm::vec3, 3>) : 0) + 32;
        return uint64_t(camera_.width) * camera_.height * camera_.layers * perPixel;
    }
    uint64_t outputBytes(uint64_t receivers) const override {
        // Nine full-frame float channels (more with per-light or deep layers), the RGB preview and
        // stb's in-memory PNG encoding of it (filtered rows and zlib output, about twice the
        // image), the luminance copy the exposure is sorted from, and OpenEXR's block buffers.
        const uint64_t pixels = uint64_t(camera_.width) * camera_.height;
        return pixels * (9 * 4 * uint64_t(camera_.layers) + 3 + 2 * 3) + receivers * 4 + (2ull << 20);
    }
    void scan(std::span<const Triangle> chunk) override { raster().add(chunk); }
    ReceiverSet receivers() override {
        ReceiverSet set = raster().finish();
        if (smooth_) bend_.emplace(raster_->takeTriangles(), set.normal, lights_);
        raster_.reset();
        return set;
    }
    bool wantsRescan() const override { return smooth_; }
    void rescan(std::span<const Triangle> chunk) override {
        if (bend_) bend_->add(chunk);
    }
    void write(const OutputContext& c) override {
        writeCameraOutputs(c.scene, c.receivers, c.samples, c.results, c.output, bend_ ? &*bend_ : nullptr);
    }

private:
    // The z-buffer is allocated when the scan starts, not when the scene is validated.
    CameraRasterizer& raster() {
        if (!raster_) {
            raster_.emplace(camera_);
            if (smooth_) raster_->recordTriangles();
        }
        return *raster_;
    }
    CameraDesc camera_;
    bool smooth_;
    std::vector<LightDirection> lights_;
    std::optional<CameraRasterizer> raster_;
    std::optional<VertexBend> bend_;
};

}  // namespace

std::unique_ptr<ReceiverKind> makeCameraKind(const JsonParams& j, const SceneDesc& scene) {
    CameraDesc c;
    c.where = j.where();
    c.eye = j.vec3("eye"), c.target = j.vec3("target"), c.up = j.vec3("up", c.up);
    c.fovDeg = j.number("fov_deg", c.fovDeg);
    c.width = int(j.integer("width", c.width, 1, 65536));
    c.height = int(j.integer("height", c.height, 1, 65536));
    c.layers = int(j.integer("layers", c.layers, 1, 16));
    return std::make_unique<CameraKind>(c, scene);
}

}  // namespace penumbra
