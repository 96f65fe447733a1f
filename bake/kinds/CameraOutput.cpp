#include "bake/kinds/CameraOutput.h"

#include "bake/ExrMetadata.h"
#include "bake/output/ImageWriters.h"
#include "bake/output/PreviewTone.h"
#include "stream/util/AtomicFile.h"

#include <glm/geometric.hpp>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numeric>

namespace penumbra {
std::string previewPath(const std::string& output) {
    return std::filesystem::path(output).replace_extension(".png").string();
}

std::vector<std::string> previewOutputs(const std::string& output) { return {previewPath(output)}; }

glm::vec3 shadedIrradiance(const ReceiverSet& receivers, const ReceiverResults& results, size_t r,
                           const VertexBend* smooth) {
    if (!smooth) return results.irradiance[r];
    glm::dvec3 sum(0.0);
    for (int l = 0; l < results.lights; ++l)
        sum += glm::dvec3(results.irradianceOf(r, l)) *
               smooth->factor(r, glm::dvec3(receivers.position[r]), glm::dvec3(receivers.normal[r]), l);
    return glm::vec3(sum);
}

namespace {

/// Rows of every channel held at once while writing (a multiple of OpenEXR's 16-line ZIP blocks).
constexpr int kStripRows = 64;

/// One refined pixel: its sub-pixel receivers [begin, end).
struct RefinedPixel {
    uint32_t pixel;
    size_t begin, end;
};

/// Everything the strips are filled from, in pixel order: first-pass receivers sorted by pixel,
/// refined pixels sorted by pixel, and the preview's exposure. Per receiver, not per pixel.
struct CameraLayout {
    size_t pixels = 0, layers = 1, firstPass = 0, front = 0;
    int lightLayers = 0;  // per-light channel groups (0 with one light)
    ExrColour colour = ExrColour::Irradiance;
    size_t perLayer = 9;  // channels per depth layer (cameraChannels())
    std::vector<uint32_t> order;
    std::vector<RefinedPixel> refined;
    PreviewTone tone;
};

/// Channels per depth layer: R, G, B, A, V, Z, N.XYZ, and the irradiance when RGB holds V.
size_t channelsPerLayer(ExrColour colour) { return colour == ExrColour::Visibility ? 12 : 9; }

CameraLayout layoutOf(const ReceiverSet& receivers, const ReceiverResults& results, const VertexBend* smooth,
                      const CameraRefinement& refinement, ExrColour colour) {
    CameraLayout c;
    c.pixels = size_t(receivers.width) * receivers.height;
    c.colour = colour, c.perLayer = channelsPerLayer(colour);
    // Deep cameras: receivers of layer k >= 1 (pixel >= k * W * H) go to "layer<k>.*" channels.
    for (uint32_t px : receivers.pixel) c.layers = std::max(c.layers, size_t(px / c.pixels) + 1);
    c.firstPass = std::min(refinement.firstPass, receivers.size());
    // The per-light layers and the preview show the nearest surface (layer 0, listed first).
    while (c.front < c.firstPass && receivers.pixel[c.front] < c.pixels) ++c.front;
    c.lightLayers = results.lights > 1 ? results.lights : 0;
    c.order.resize(c.firstPass);
    std::iota(c.order.begin(), c.order.end(), 0u);
    // Camera receivers come in pixel order; deep layers and other kinds' layouts may not.
    const auto byPixel = [&](uint32_t a, uint32_t b) { return receivers.pixel[a] % c.pixels < receivers.pixel[b] % c.pixels; };
    if (!std::is_sorted(c.order.begin(), c.order.end(), byPixel)) std::stable_sort(c.order.begin(), c.order.end(), byPixel);
    for (size_t i = c.firstPass; i < receivers.size();) {
        size_t end = i;
        while (end < receivers.size() && receivers.pixel[end] == receivers.pixel[i]) ++end;
        c.refined.push_back({receivers.pixel[i], i, end});
        i = end;
    }
    std::stable_sort(c.refined.begin(), c.refined.end(), [](const RefinedPixel& a, const RefinedPixel& b) { return a.pixel < b.pixel; });
    // Preview exposure: the brighter lit surfaces sit near white (PreviewTone.h).
    std::vector<float> luminance(c.front);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, c.front, 4096), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) luminance[i] = previewLuminance(shadedIrradiance(receivers, results, i, smooth));
    });
    c.tone = previewTone(luminance);
    return c;
}

/// Offsets of the channels within one depth layer's block (cameraChannels() order).
enum LayerChannel : size_t { kR, kG, kB, kA, kV, kZ, kNX, kNY, kNZ, kER, kEG, kEB };

/// Fills rows [y0, y0 + rows) of every channel and of the preview, walking the receivers of those
/// pixels (cursors advance strip by strip).
class StripFiller {
public:
    StripFiller(const CameraLayout& c, const CameraDesc& camera, const ReceiverSet& r, const ReceiverResults& res,
                const VertexBend* smooth, const CameraRefinement& refinement)
        : c_(c), eye_(camera.eye), forward_(cameraBasis(camera).forward), r_(r), res_(res), smooth_(smooth),
          refinement_(refinement), width_(size_t(r.width)), channels_(channelCount(c)), data_(channels_ * kStripRows * width_),
          rgb_(kStripRows * width_ * 3) {}

    static size_t channelCount(const CameraLayout& c) { return c.perLayer * c.layers + 4 * size_t(c.lightLayers); }
    static uint64_t bytes(const CameraLayout& c, int width) {
        return channelCount(c) * kStripRows * uint64_t(width) * 4 + kStripRows * uint64_t(width) * 3;
    }
    std::vector<const float*> channels(int rows) const {
        std::vector<const float*> out;
        for (size_t ch = 0; ch < channels_; ++ch) out.push_back(&data_[ch * kStripRows * width_]);
        return out;
    }
    std::span<const uint8_t> preview(int rows) const { return std::span<const uint8_t>(rgb_).first(size_t(rows) * width_ * 3); }

    /// Rows are filled in parallel: a row's receivers and refined pixels are a contiguous run of
    /// the pixel-sorted lists and write only that row's pixels, in the order a serial fill would.
    void fill(int y0, int rows) {
        const size_t first = size_t(y0) * width_;
        // Where each row's receivers and refined pixels begin in the sorted lists.
        std::vector<size_t> orderAt(size_t(rows) + 1), refinedAt(size_t(rows) + 1);
        for (int y = 0; y <= rows; ++y) {
            const size_t end = first + size_t(y) * width_;
            for (; next_ < c_.order.size() && r_.pixel[c_.order[next_]] % c_.pixels < end; ++next_) {}
            for (; nextRefined_ < c_.refined.size() && c_.refined[nextRefined_].pixel < end; ++nextRefined_) {}
            orderAt[size_t(y)] = next_, refinedAt[size_t(y)] = nextRefined_;
        }
        tbb::parallel_for(tbb::blocked_range<int>(0, rows, 4), [&](const tbb::blocked_range<int>& range) {
            for (int y = range.begin(); y != range.end(); ++y) fillRow(size_t(y), first, orderAt, refinedAt);
        });
    }

private:
    void fillRow(size_t y, size_t first, const std::vector<size_t>& orderAt, const std::vector<size_t>& refinedAt) {
        const size_t row = y * width_;
        for (size_t ch = 0; ch < channels_; ++ch) std::fill_n(&at(ch, row), width_, 0.f);
        for (size_t layer = 0; layer < c_.layers; ++layer)  // no surface: infinitely far
            std::fill_n(&at(c_.perLayer * layer + kZ, row), width_, std::numeric_limits<float>::infinity());
        for (size_t px = row; px < row + width_; ++px) setColour(px, glm::vec3(PreviewTone::kBackground));
        for (size_t k = orderAt[y]; k < orderAt[y + 1]; ++k) firstPass(c_.order[k], first);
        for (size_t k = refinedAt[y]; k < refinedAt[y + 1]; ++k) refinedPixel(c_.refined[k], first);
    }
    float& at(size_t channel, size_t local) { return data_[channel * kStripRows * width_ + local]; }
    void setColour(size_t local, const glm::vec3& c) {
        for (int k = 0; k < 3; ++k) rgb_[3 * local + size_t(k)] = encodeSrgb(c[k]);
    }
    /// Camera-space depth of receiver @p i along the view axis.
    float viewDepth(size_t i) const { return float(glm::dot(glm::dvec3(r_.position[i]) - eye_, forward_)); }
    /// R, G, B (and the irradiance pass when they hold V) of layer block @p base.
    void setRgb(size_t base, size_t local, float v, const glm::dvec3& e) {
        const bool grey = c_.colour == ExrColour::Visibility;
        for (size_t k = 0; k < 3; ++k) {
            at(base + kR + k, local) = grey ? v : float(e[int(k)]);
            if (grey) at(base + kER + k, local) = float(e[int(k)]);
        }
        at(base + kV, local) = v;
    }
    void setSurface(size_t base, size_t local, size_t i) {
        at(base + kZ, local) = viewDepth(i);
        for (size_t k = 0; k < 3; ++k) at(base + kNX + k, local) = r_.normal[i][int(k)];
    }

    void firstPass(uint32_t i, size_t first) {
        const size_t base = c_.perLayer * (r_.pixel[i] / c_.pixels), local = r_.pixel[i] % c_.pixels - first;
        setRgb(base, local, res_.visibility[i], glm::dvec3(res_.irradiance[i]));
        at(base + kA, local) = 1.f;
        setSurface(base, local, i);
        if (i >= c_.front) return;
        for (int l = 0; l < c_.lightLayers; ++l) {
            const glm::vec3 el = res_.irradianceOf(i, l);
            const float v[4] = {res_.visibilityOf(i, l), el.x, el.y, el.z};
            for (size_t k = 0; k < 4; ++k) at(c_.perLayer * c_.layers + 4 * size_t(l) + k, local) = v[k];
        }
        setColour(local, c_.tone(shadedIrradiance(r_, res_, i, smooth_)));
    }

    /// A refined pixel: the mean over its sub-pixel receivers (summed in double, in receiver order).
    void refinedPixel(const RefinedPixel& g, size_t first) {
        const size_t local = g.pixel - first;
        const double count = double(g.end - g.begin);
        double v = 0;
        glm::dvec3 sumE(0.0), shade(0.0);
        std::vector<double> lightSums(4 * size_t(c_.lightLayers), 0.0);
        for (size_t r = g.begin; r < g.end; ++r) {
            v += res_.visibility[r], sumE += glm::dvec3(res_.irradiance[r]);
            shade += glm::dvec3(shadedIrradiance(r_, res_, r, smooth_));
            for (int l = 0; l < c_.lightLayers; ++l) {
                const glm::vec3 el = res_.irradianceOf(r, l);
                lightSums[4 * size_t(l)] += res_.visibilityOf(r, l);
                lightSums[4 * size_t(l) + 1] += el.x, lightSums[4 * size_t(l) + 2] += el.y, lightSums[4 * size_t(l) + 3] += el.z;
            }
        }
        setRgb(0, local, float(v / count), glm::dvec3(glm::vec3(sumE / count)));
        for (size_t k = 0; k < lightSums.size(); ++k) at(c_.perLayer * c_.layers + k, local) = float(lightSums[k] / count);
        if (at(kA, local) == 0.f) setSurface(0, local, g.begin);  // the centre saw nothing: the first covered sub-pixel's
        const float a = float(count / refinement_.subPixels);
        at(kA, local) = a;
        // R, G, B are associated with A, as OpenEXR defines them and compositors read them (a
        // straight colour over a background gave edges a bright halo); the data layers keep the
        // covered sub-pixels' mean.
        for (size_t k = kR; k <= kB; ++k) at(k, local) *= a;
        // Coverage blends with the background.
        setColour(local, a * c_.tone(glm::vec3(shade / count)) + (1.f - a) * glm::vec3(PreviewTone::kBackground));
    }

    const CameraLayout& c_;
    glm::dvec3 eye_, forward_;
    const ReceiverSet& r_;
    const ReceiverResults& res_;
    const VertexBend* smooth_;
    const CameraRefinement& refinement_;
    size_t width_, channels_;
    std::vector<float> data_;
    std::vector<uint8_t> rgb_;
    size_t next_ = 0, nextRefined_ = 0;
};

}  // namespace

std::vector<ExrChannelSpec> cameraChannels(int layers, int lights, ExrColour colour) {
    std::vector<ExrChannelSpec> out;
    for (int layer = 0; layer < layers; ++layer) {
        const std::string prefix = layer == 0 ? "" : fmt::format("layer{}.", layer);
        const std::string combined = layer == 0 ? "" : prefix + "Combined.";
        for (const char* n : {"R", "G", "B", "A"}) out.push_back({combined + n});
        out.push_back({prefix + "visibility.V"});
        out.push_back({prefix + "depth.Z", true});
        for (const char* n : {"X", "Y", "Z"}) out.push_back({prefix + "normal." + n});
        if (colour == ExrColour::Visibility)
            for (const char* n : {"R", "G", "B"}) out.push_back({prefix + "irradiance." + n});
    }
    for (int l = 0; lights > 1 && l < lights; ++l) {
        out.push_back({fmt::format("light{}.visibility.V", l)});
        for (const char* n : {"R", "G", "B"}) out.push_back({fmt::format("light{}.irradiance.{}", l, n)});
    }
    return out;
}

uint64_t cameraOutputBytes(int width, int layers, int lights, uint64_t receivers, const ExrSettings& exr) {
    CameraLayout c;
    c.layers = size_t(layers), c.lightLayers = lights > 1 ? lights : 0, c.perLayer = channelsPerLayer(exr.colour);
    // Per receiver: its place in the pixel order (4), its preview luminance (4) and, for refined
    // receivers, a share of their pixel's group (24). Per strip: the channels and the preview rows,
    // OpenEXR's buffers (ExrStripWriter::bytes) and the PNG's zlib.
    return receivers * (4 + 4 + 24) + StripFiller::bytes(c, width) +
           ExrStripWriter::bytes(width, StripFiller::channelCount(c), exr.format) + PngStripWriter::bytes(width, 3) + (1u << 20);
}

void writeCameraOutputs(const SceneDesc& scene, const CameraDesc& camera, const ReceiverSet& receivers,
                        const LightSamples& samples, const ReceiverResults& results, const std::string& output,
                        const VertexBend* smooth, const CameraRefinement& refinement, ProgressReporter* progress) {
    const int W = receivers.width, H = receivers.height;
    const CameraLayout layout = layoutOf(receivers, results, smooth, refinement, scene.exr.colour);
    std::vector<ExrAttribute> attributes = bakeAttributes(scene, samples, scene.exr.colour);
    for (ExrAttribute& a : cameraAttributes(camera)) attributes.push_back(std::move(a));
    ensureParentDirectory(output);
    ExrStripWriter exr(output, W, H, cameraChannels(int(layout.layers), results.lights, scene.exr.colour), attributes,
                       scene.exr.format);
    PngStripWriter png(previewPath(output), W, H, 3);
    StripFiller strips(layout, camera, receivers, results, smooth, refinement);
    for (int y = 0; y < H; y += kStripRows) {
        const int rows = std::min(kStripRows, H - y);
        strips.fill(y, rows);
        // Two files, two compressors: the PNG's deflate runs beside the EXR's.
        tbb::parallel_invoke([&] { exr.write(rows, strips.channels(rows)); }, [&] { png.write(rows, strips.preview(rows)); });
        if (progress) progress->update(uint64_t(rows));
    }
    exr.commit();
    png.commit();
}

}  // namespace penumbra
