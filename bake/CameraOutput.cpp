#include "bake/CameraOutput.h"

#include "bake/ImageWriters.h"
#include "stream/AtomicFile.h"

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <filesystem>
#include <cmath>
#include <numeric>

namespace penumbra {
namespace {

/// Emitting direction of a planar light, or zero for volumetric lights (no emitter cosine).
glm::dvec3 emitterNormal(const LightDesc& l) {
    switch (l.type) {
        case LightType::Rect: return glm::normalize(glm::cross(l.u, l.v));
        case LightType::Disk: return glm::normalize(l.normal);
        case LightType::Polygon: {
            glm::dvec3 n(0.0);
            for (size_t i = 1; i + 1 < l.polygon.size(); ++i)
                n += glm::cross(l.polygon[i] - l.polygon[0], l.polygon[i + 1] - l.polygon[0]);
            return glm::normalize(n);
        }
        case LightType::Sphere: return glm::dvec3(0.0);
    }
    return glm::dvec3(0.0);
}

}  // namespace

std::string previewPath(const std::string& output) {
    return std::filesystem::path(output).replace_extension(".png").string();
}

std::vector<glm::vec3> irradiance(const std::vector<LightDesc>& lights, const LightSamples& samples,
                                  const ReceiverSet& receivers, std::span<const uint32_t> sampleSets,
                                  const VisibilityMasks& masks) {
    struct PerLight {
        glm::dvec3 normal, weight;  // weight = radiance * area per sample
    };
    std::vector<PerLight> per;
    for (const LightDesc& l : lights) {
        double area = l.type == LightType::Sphere ? M_PI * l.radius * l.radius : l.area();
        per.push_back({emitterNormal(l), l.radiance * (area / l.samples)});
    }
    std::vector<glm::vec3> out(receivers.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, receivers.size(), 256), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t r = range.begin(); r != range.end(); ++r) {
            const glm::dvec3 p(receivers.position[r]), n(receivers.normal[r]);
            glm::dvec3 e(0.0);
            for (int k = 0; k < masks.groups; ++k) {
                const LightSampleGroup& g = samples.groups[k];
                const PerLight& light = per[g.light];
                uint64_t visible = ~masks.row(r)[k] & g.fullMask();
                for (; visible; visible &= visible - 1) {
                    int j = __builtin_ctzll(visible);
                    glm::dvec3 d = glm::dvec3(samples.position(int(sampleSets[r]), int(g.first) + j)) - p;
                    double dist2 = glm::dot(d, d);
                    if (!(dist2 > 0)) continue;
                    glm::dvec3 w = d / std::sqrt(dist2);
                    double cosReceiver = std::max(0.0, glm::dot(n, w));
                    double cosEmitter = glm::dot(light.normal, light.normal) > 0 ? std::max(0.0, -glm::dot(light.normal, w)) : 1.0;
                    e += light.weight * (cosReceiver * cosEmitter / dist2);
                }
            }
            out[r] = glm::vec3(e);
        }
    });
    return out;
}

void writeCameraOutputs(const SceneDesc& scene, const ReceiverSet& receivers, const LightSamples& samples,
                        std::span<const uint32_t> sampleSets, const VisibilityMasks& masks,
                        std::span<const float> visibility) {
    const int W = receivers.width, H = receivers.height;
    const size_t pixels = size_t(W) * H;
    std::vector<float> V(pixels, 0.f), A(pixels, 0.f), Z(pixels, 0.f), ER(pixels, 0.f), EG(pixels, 0.f), EB(pixels, 0.f);
    std::vector<float> NX(pixels, 0.f), NY(pixels, 0.f), NZ(pixels, 0.f);
    std::vector<glm::vec3> e = irradiance(scene.lights, samples, receivers, sampleSets, masks);
    for (size_t i = 0; i < receivers.size(); ++i) {
        uint32_t px = receivers.pixel[i];
        V[px] = visibility[i], A[px] = 1.f, Z[px] = receivers.depth[i];
        ER[px] = e[i].x, EG[px] = e[i].y, EB[px] = e[i].z;
        NX[px] = receivers.normal[i].x, NY[px] = receivers.normal[i].y, NZ[px] = receivers.normal[i].z;
    }
    ExrChannel channels[] = {{"V", V.data()},   {"A", A.data()},    {"Z", Z.data()},    {"E.R", ER.data()}, {"E.G", EG.data()},
                             {"E.B", EB.data()}, {"N.X", NX.data()}, {"N.Y", NY.data()}, {"N.Z", NZ.data()}};
    int sampleCount = samples.sampleCount;
    ExrAttribute attributes[] = {
        {"penumbra:lights", std::to_string(scene.lights.size())},
        {"penumbra:samples", std::to_string(sampleCount)},
        {"penumbra:sampleSets", std::to_string(samples.sets)},
        {"penumbra:seed", std::to_string(scene.seed)},
    };
    ensureParentDirectory(scene.output);
    writeExr(scene.output, W, H, channels, attributes);

    // Preview: white Lambert under the lights plus a little ambient, exposed so that the brighter
    // lit surfaces sit near white (99th percentile of luminance).
    std::vector<float> sorted;
    for (const glm::vec3& x : e) sorted.push_back(0.2126f * x.x + 0.7152f * x.y + 0.0722f * x.z);
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
    for (size_t i = 0; i < receivers.size(); ++i) {
        uint32_t px = receivers.pixel[i];
        glm::vec3 c = glm::vec3(ambient) + exposure * e[i];
        rgb[3 * px] = encodeSrgb(c.x), rgb[3 * px + 1] = encodeSrgb(c.y), rgb[3 * px + 2] = encodeSrgb(c.z);
    }
    writePng8(previewPath(scene.output), W, H, 3, rgb);
}

}  // namespace penumbra
