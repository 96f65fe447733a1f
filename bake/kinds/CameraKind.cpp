#include "bake/kinds/CameraKind.h"

#include "bake/kinds/CameraOutput.h"
#include "bake/Scene.h"
#include "bake/shading/SmoothShading.h"
#include "receivers/CameraReceivers.h"
#include "stream/util/Error.h"

#include <cmath>
#include <optional>

namespace penumbra {

std::vector<uint32_t> highContrastPixels(const ReceiverSet& receivers, std::span<const float> visibility, size_t firstPass,
                                         double threshold) {
    const int W = receivers.width, H = receivers.height;
    const size_t pixels = size_t(W) * H;
    std::vector<float> v(pixels, NAN);  // NaN: no surface
    for (size_t i = 0; i < std::min(firstPass, receivers.size()); ++i)
        if (receivers.pixel[i] < pixels) v[receivers.pixel[i]] = visibility[i];
    std::vector<uint32_t> out;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const float a = v[size_t(y) * W + x];
            bool contrast = false;
            for (int dy = -1; dy <= 1 && !contrast; ++dy)
                for (int dx = -1; dx <= 1 && !contrast; ++dx) {
                    const int nx = x + dx, ny = y + dy;
                    if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= W || ny >= H) continue;
                    const float b = v[size_t(ny) * W + nx];
                    contrast = std::isnan(a) != std::isnan(b) || std::abs(double(a) - double(b)) > threshold;
                }
            if (contrast) out.push_back(uint32_t(size_t(y) * W + x));
        }
    return out;
}

namespace {

class CameraKind final : public ReceiverKind {
public:
    CameraKind(const CameraDesc& camera, const CameraAntialias& aa, const SceneDesc& scene)
        : camera_(camera), aa_(aa), smooth_(scene.smoothShading), lights_(lightDirections(scene.lights)),
          lightCount_(scene.lights.size()), exr_(scene.exr), classes_(scene.receiverClasses),
          alpha_(scene.options.alphaTable ? scene.options.alphaTable : AlphaTable::builtin()) {
        validateCamera(camera);
    }
    uint64_t outputBytes(uint64_t receivers) const override {
        // Strips of rows, never the full frame (CameraOutput.h).
        return cameraOutputBytes(camera_.width, camera_.layers, int(lightCount_), receivers, exr_);
    }
    uint64_t maxResidentBytes(uint64_t receivers, std::optional<uint64_t> triangles) const override {
        if (!smooth_) return 0;
        if (bend_) return bend_->plannedBytes(receivers, triangles.value_or(receivers));  // the visible triangles are known
        return VertexBend::boundBytes(receivers, triangles.value_or(receivers), lights_.size());
    }
    std::optional<uint64_t> receiverBound() const override {
        return uint64_t(camera_.width) * camera_.height * camera_.layers;
    }
    // The scan rasterizes the receivers. Smooth shading finds its receivers' triangles in the
    // stream-order rescan, then the faces around their vertices in the cast pass; a refinement
    // rasterizes its pixels again.
    bool wantsPass(StreamPass pass) const override { return pass == StreamPass::Scan || pass == StreamPass::Refine || smooth_; }
    void consume(StreamPass pass, const StreamChunk& chunk) override {
        switch (pass) {
        case StreamPass::Scan: raster().add(chunk.triangles); break;
        case StreamPass::Rescan:
            if (bend_) bend_->recover(chunk.triangles);
            break;
        case StreamPass::Cast:
            if (bend_) bend_->add(chunk.triangles);
            break;
        case StreamPass::Refine: raster_->add(chunk.triangles); break;
        }
    }
    uint64_t passBytes(StreamPass pass) const override {
        if (pass == StreamPass::Scan) {
            // The z-buffer (plus the triangle id per pixel for smooth shading) and, at the end of
            // the pass, the receiver set made from it (32 bytes per covered pixel) and the ids
            // moved to the receivers' order (8).
            // Per-object receiver classes: a byte per pixel and one per receiver.
            uint64_t perPixel = CameraRasterizer::kBytesPerPixel + (smooth_ ? 2 * sizeof(uint64_t) : 0) + 32 + classBytes();
            return uint64_t(camera_.width) * camera_.height * camera_.layers * perPixel;
        }
        if (pass == StreamPass::Refine)
            return refinedPixels_ * uint64_t(aa_.samples) * (CameraRasterizer::kBytesPerPixel + (smooth_ ? 36 : 0) + 32 + classBytes()) +
                   uint64_t(camera_.width) * camera_.height * 4;
        return 0;
    }
    ReceiverSet receivers() override {
        ReceiverSet set = raster().finish();
        if (smooth_) bend_.emplace(lights_), bend_->expectTriangleIds(raster_->takeTriangleIds());
        takeClasses(set);
        return set;
    }
    uint64_t residentBytes() const override { return bend_ ? bend_->bytes() : 0; }
    bool refine(const ReceiverSet& receivers, const ReceiverResults& results) override {
        if (aa_.samples == 0) return false;
        std::vector<uint32_t> pixels = highContrastPixels(receivers, results.visibility, receivers.size(), aa_.threshold);
        refinedPixels_ = pixels.size();
        if (pixels.empty()) return false;
        const int n = int(std::lround(std::sqrt(double(aa_.samples))));
        raster_.emplace(camera_, n, pixels);
        raster_->seeThroughCutOuts(alpha_);
        if (smooth_) raster_->recordTriangles();
        if (classes_.size() > 1) raster_->recordClasses();
        return true;
    }
    bool mayRefine() const override { return aa_.samples > 0; }
    uint64_t maxRefinedReceivers() const override { return refinedPixels_ * uint64_t(aa_.samples); }
    ReceiverSet refinedReceivers() override {
        ReceiverSet set = raster_->finish();
        if (bend_) bend_->addTriangles(raster_->takeTriangles(), set.normal);
        takeClasses(set);
        addedReceivers_ = set.size();
        return set;
    }
    nlohmann::json stats() const override {
        nlohmann::json s = nlohmann::json::object();
        if (bend_) s["smooth_shading"] = {{"vertices", bend_->vertices()}, {"bytes", bend_->bytes()}};
        if (aa_.samples > 0)
            s["antialias"] = {{"threshold", aa_.threshold},
                              {"samples", aa_.samples},
                              {"refined_pixels", refinedPixels_},
                              {"added_receivers", addedReceivers_}};
        return s;
    }
    void write(const OutputContext& c) override {
        CameraRefinement refinement{c.firstPass, aa_.samples > 0 ? aa_.samples : 1};
        writeCameraOutputs(c.scene, camera_, c.receivers, c.samples, c.results, c.output, bend_ ? &*bend_ : nullptr, refinement,
                           c.progress);
    }
    uint64_t outputWork() const override { return uint64_t(camera_.height); }

private:
    // The z-buffer is allocated when the scan starts, not when the scene is validated.
    CameraRasterizer& raster() {
        if (!raster_) {
            raster_.emplace(camera_);
            raster_->seeThroughCutOuts(alpha_);
            if (smooth_) raster_->recordTriangleIds();
            if (classes_.size() > 1) raster_->recordClasses();
        }
        return *raster_;
    }
    uint64_t classBytes() const { return classes_.size() > 1 ? 2 : 0; }
    /// The entries' receive_shadows and receiver_offset on the receivers the rasterizer made
    /// (after smooth shading took the normals it needs), and the rasterizer's end.
    void takeClasses(ReceiverSet& set) {
        applyReceiverClasses(set, 0, raster_->takeClasses(), classes_);
        raster_.reset();
    }
    CameraDesc camera_;
    CameraAntialias aa_;
    bool smooth_;
    std::vector<LightDirection> lights_;
    size_t lightCount_;
    ExrSettings exr_;
    std::vector<ReceiverClass> classes_;  ///< SceneDesc::receiverClasses
    /// The scene's cut-outs, which the camera sees through; filled before the scan reads geometry.
    std::shared_ptr<const AlphaTable> alpha_;
    std::optional<CameraRasterizer> raster_;
    std::optional<VertexBend> bend_;
    uint64_t refinedPixels_ = 0, addedReceivers_ = 0;
};

}  // namespace

CameraDesc readCameraView(const JsonParams& j) {
    CameraDesc c;
    c.where = j.where();
    c.eye = j.vec3("eye"), c.target = j.vec3("target"), c.up = j.vec3("up", c.up);
    c.fovDeg = j.number("fov_deg", c.fovDeg);
    c.width = int(j.integer("width", c.width, 1, 65536));
    c.height = int(j.integer("height", c.height, 1, 65536));
    return c;
}

std::unique_ptr<ReceiverKind> makeCameraKind(const JsonParams& j, const SceneDesc& scene, KindUse use) {
    requireOutputExtension(scene, {".exr"}, "camera");
    CameraDesc c = readCameraView(j);
    c.layers = int(j.integer("layers", c.layers, 1, 16));
    CameraAntialias aa;
    if (const nlohmann::json* raw = j.raw("antialias")) {
        if (!raw->is_object()) fail(j.where("antialias"), "expected an object such as {{\"threshold\": 0.1, \"samples\": 4}}");
        JsonParams a(*raw, j.file(), j.path("antialias"));
        aa.threshold = a.number("threshold", aa.threshold);
        if (!(aa.threshold >= 0 && aa.threshold < 1)) fail(a.where("threshold"), "must be in [0, 1), got {}", aa.threshold);
        aa.samples = int(a.integer("samples", 4, 4, 64));
        const int n = int(std::lround(std::sqrt(double(aa.samples))));
        if (n * n != aa.samples) fail(a.where("samples"), "must be a square (4, 9, 16, ..., 64), got {}", aa.samples);
        if (c.layers != 1) fail(a.where(), "antialiasing needs one layer (\"layers\": 1)");
        if (int64_t(c.width) * n > 65536 || int64_t(c.height) * n > 65536)
            fail(a.where("samples"), "width and height times sqrt(samples) must be at most 65536");
        a.finish();
    }
    if (use == KindUse::Validate) {
        validateCamera(c);
        return nullptr;
    }
    return std::make_unique<CameraKind>(c, aa, scene);
}

namespace {
const ReceiverKindRegistration kCamera{"camera", &makeCameraKind, ".exr", &previewOutputs};
}  // namespace

}  // namespace penumbra
