#include "bake/CameraOutput.h"

#include "bake/ImageWriters.h"
#include "stream/AtomicFile.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <cmath>
#include <numeric>

namespace penumbra {
std::string previewPath(const std::string& output) {
    return std::filesystem::path(output).replace_extension(".png").string();
}

std::vector<ExrAttribute> cameraAttributes(const SceneDesc& scene, const LightSamples& samples) {
    std::vector<ExrAttribute> a = {
        {"penumbra:lights", std::to_string(scene.lights.size())},
        {"penumbra:samples", std::to_string(samples.sampleCount)},
        {"penumbra:sampleSets", std::to_string(samples.sets)},
        {"penumbra:seed", std::to_string(scene.seed)},
        {"penumbra:groupSize", std::to_string(scene.options.groupSize)},
    };
    static const char* typeNames[] = {"rect", "disk", "sphere", "polygon", "sun"};
    for (size_t i = 0; i < scene.lights.size(); ++i) {
        const LightDesc& l = scene.lights[i];
        std::string text = fmt::format("type={} samples={} sample_sets={}", typeNames[int(l.type)], l.samples, l.sampleSets);
        if (l.type == LightType::Sun)
            text += fmt::format(" direction=[{},{},{}] angular_diameter_deg={} irradiance=[{},{},{}]", l.direction.x,
                                l.direction.y, l.direction.z, l.angularDiameterDeg, l.irradiance.x, l.irradiance.y,
                                l.irradiance.z);
        else
            text += fmt::format(" center=[{},{},{}] area={} radiance=[{},{},{}]", l.center.x, l.center.y, l.center.z,
                                l.area(), l.radiance.x, l.radiance.y, l.radiance.z);
        a.push_back({fmt::format("penumbra:light{}", i), text});
    }
    return a;
}

glm::vec3 shadedIrradiance(const ReceiverSet& receivers, const ReceiverResults& results, size_t r,
                           const VertexBend* smooth) {
    if (!smooth) return results.irradiance[r];
    glm::dvec3 sum(0.0);
    for (int l = 0; l < results.lights; ++l)
        sum += glm::dvec3(results.irradianceOf(r, l)) *
               smooth->factor(r, glm::dvec3(receivers.position[r]), glm::dvec3(receivers.normal[r]), l);
    return glm::vec3(sum);
}

void writeCameraOutputs(const SceneDesc& scene, const ReceiverSet& receivers, const LightSamples& samples,
                        const ReceiverResults& results, const std::string& output, const VertexBend* smooth,
                        const CameraRefinement& refinement) {
    const int W = receivers.width, H = receivers.height;
    const size_t pixels = size_t(W) * H;
    std::vector<float> V(pixels, 0.f), A(pixels, 0.f), Z(pixels, 0.f), ER(pixels, 0.f), EG(pixels, 0.f), EB(pixels, 0.f);
    std::vector<float> NX(pixels, 0.f), NY(pixels, 0.f), NZ(pixels, 0.f);
    const std::vector<glm::vec3>& e = results.irradiance;
    // Deep cameras: receivers of layer k >= 1 (pixel >= k * W * H) go to "layer<k>.*" channels.
    size_t layers = 1;
    for (uint32_t px : receivers.pixel) layers = std::max(layers, size_t(px / pixels) + 1);
    std::vector<std::vector<float>> deep((layers - 1) * 9, std::vector<float>(pixels, 0.f));
    const size_t firstPass = std::min(refinement.firstPass, receivers.size());
    for (size_t i = 0; i < firstPass; ++i) {
        const size_t layer = receivers.pixel[i] / pixels, px = receivers.pixel[i] % pixels;
        if (layer > 0) {
            float* d[9];
            for (int c = 0; c < 9; ++c) d[c] = deep[(layer - 1) * 9 + c].data();
            float values[9] = {results.visibility[i], 1.f, receivers.depth[i], e[i].x, e[i].y, e[i].z,
                               receivers.normal[i].x, receivers.normal[i].y, receivers.normal[i].z};
            for (int c = 0; c < 9; ++c) d[c][px] = values[c];
            continue;
        }
        V[px] = results.visibility[i], A[px] = 1.f, Z[px] = receivers.depth[i];
        ER[px] = e[i].x, EG[px] = e[i].y, EB[px] = e[i].z;
        NX[px] = receivers.normal[i].x, NY[px] = receivers.normal[i].y, NZ[px] = receivers.normal[i].z;
    }
    std::vector<ExrChannel> channels = {{"V", V.data()},   {"A", A.data()},    {"Z", Z.data()},
                                        {"E.R", ER.data()}, {"E.G", EG.data()}, {"E.B", EB.data()},
                                        {"N.X", NX.data()}, {"N.Y", NY.data()}, {"N.Z", NZ.data()}};
    std::vector<std::string> deepNames;
    for (size_t layer = 1; layer < layers; ++layer)
        for (const char* c : {"V", "A", "Z", "E.R", "E.G", "E.B", "N.X", "N.Y", "N.Z"})
            deepNames.push_back(fmt::format("layer{}.{}", layer, c));
    for (size_t c = 0; c < deep.size(); ++c) channels.push_back({deepNames[c], deep[c].data()});
    // The per-light layers and the preview show the nearest surface (layer 0, listed first).
    size_t front = 0;
    while (front < firstPass && receivers.pixel[front] < pixels) ++front;
    // Several lights: each gets its own layer, "light<i>.V" and "light<i>.E.R/G/B".
    const int lightCount = results.lights;
    std::vector<std::vector<float>> perLight(lightCount > 1 ? size_t(lightCount) * 4 : 0, std::vector<float>(pixels, 0.f));
    std::vector<std::string> names;
    for (int l = 0; l < lightCount && lightCount > 1; ++l) {
        for (size_t i = 0; i < front; ++i) {
            uint32_t px = receivers.pixel[i];
            glm::vec3 el = results.irradianceOf(i, l);
            perLight[4 * l][px] = results.visibilityOf(i, l);
            perLight[4 * l + 1][px] = el.x, perLight[4 * l + 2][px] = el.y, perLight[4 * l + 3][px] = el.z;
        }
        for (const char* c : {"V", "E.R", "E.G", "E.B"}) names.push_back(fmt::format("light{}.{}", l, c));
    }
    // Refined pixels: the mean over their sub-pixel receivers (summed in double, in receiver order).
    std::vector<std::pair<uint32_t, glm::vec3>> refinedPreview;  // pixel, premultiplied shading
    for (size_t i = firstPass; i < receivers.size();) {
        const uint32_t px = receivers.pixel[i];
        size_t end = i;
        while (end < receivers.size() && receivers.pixel[end] == px) ++end;
        const double count = double(end - i);
        double v = 0;
        glm::dvec3 sumE(0.0), shade(0.0);
        std::vector<double> lightSums(perLight.size(), 0.0);
        for (size_t r = i; r < end; ++r) {
            v += results.visibility[r], sumE += glm::dvec3(e[r]);
            shade += glm::dvec3(shadedIrradiance(receivers, results, r, smooth));
            for (int l = 0; l < int(perLight.size() / 4); ++l) {
                glm::vec3 el = results.irradianceOf(r, l);
                lightSums[4 * l] += results.visibilityOf(r, l);
                lightSums[4 * l + 1] += el.x, lightSums[4 * l + 2] += el.y, lightSums[4 * l + 3] += el.z;
            }
        }
        V[px] = float(v / count), ER[px] = float(sumE.x / count), EG[px] = float(sumE.y / count), EB[px] = float(sumE.z / count);
        for (size_t c = 0; c < perLight.size(); ++c) perLight[c][px] = float(lightSums[c] / count);
        if (A[px] == 0.f) {  // the centre saw nothing: depth and normal of the first covered sub-pixel
            Z[px] = receivers.depth[i];
            NX[px] = receivers.normal[i].x, NY[px] = receivers.normal[i].y, NZ[px] = receivers.normal[i].z;
        }
        A[px] = float(count / refinement.subPixels);
        refinedPreview.push_back({px, glm::vec3(shade / count)});
        i = end;
    }
    for (size_t c = 0; c < perLight.size(); ++c) channels.push_back({names[c], perLight[c].data()});
    ensureParentDirectory(output);
    writeExr(output, W, H, channels, cameraAttributes(scene, samples));

    // Preview: white Lambert under the lights plus a little ambient, exposed so that the brighter
    // lit surfaces sit near white (99th percentile of luminance).
    std::vector<glm::vec3> shaded(front);
    for (size_t i = 0; i < front; ++i) shaded[i] = shadedIrradiance(receivers, results, i, smooth);
    std::vector<float> sorted;
    for (const glm::vec3& x : shaded) sorted.push_back(0.2126f * x.x + 0.7152f * x.y + 0.0722f * x.z);
    float white = 1.f;
    if (!sorted.empty()) {
        size_t q = std::min(sorted.size() - 1, size_t(0.99 * double(sorted.size())));
        std::nth_element(sorted.begin(), sorted.begin() + q, sorted.end());
        white = sorted[q] > 0 ? sorted[q] : 1.f;
    }
    const float ambient = 0.06f, exposure = 0.92f / white;
    std::vector<uint8_t> rgb(pixels * 3);
    for (size_t px = 0; px < pixels; ++px) {  // background: a neutral dark grey
        rgb[3 * px] = rgb[3 * px + 1] = rgb[3 * px + 2] = encodeSrgb(0.02f);
    }
    for (size_t i = 0; i < front; ++i) {
        uint32_t px = receivers.pixel[i];
        glm::vec3 c = glm::vec3(ambient) + exposure * shaded[i];
        rgb[3 * px] = encodeSrgb(c.x), rgb[3 * px + 1] = encodeSrgb(c.y), rgb[3 * px + 2] = encodeSrgb(c.z);
    }
    for (const auto& [px, shade] : refinedPreview) {  // coverage blends with the background
        glm::vec3 c = A[px] * (glm::vec3(ambient) + exposure * shade) + (1.f - A[px]) * glm::vec3(0.02f);
        rgb[3 * px] = encodeSrgb(c.x), rgb[3 * px + 1] = encodeSrgb(c.y), rgb[3 * px + 2] = encodeSrgb(c.z);
    }
    writePng8(previewPath(output), W, H, 3, rgb);
}

}  // namespace penumbra
