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

void writeCameraOutputs(const SceneDesc& scene, const ReceiverSet& receivers, const LightSamples& samples,
                        const ReceiverResults& results, const std::string& output) {
    const int W = receivers.width, H = receivers.height;
    const size_t pixels = size_t(W) * H;
    std::vector<float> V(pixels, 0.f), A(pixels, 0.f), Z(pixels, 0.f), ER(pixels, 0.f), EG(pixels, 0.f), EB(pixels, 0.f);
    std::vector<float> NX(pixels, 0.f), NY(pixels, 0.f), NZ(pixels, 0.f);
    const std::vector<glm::vec3>& e = results.irradiance;
    for (size_t i = 0; i < receivers.size(); ++i) {
        uint32_t px = receivers.pixel[i];
        V[px] = results.visibility[i], A[px] = 1.f, Z[px] = receivers.depth[i];
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
    ensureParentDirectory(output);
    writeExr(output, W, H, channels, attributes);

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
    writePng8(previewPath(output), W, H, 3, rgb);
}

}  // namespace penumbra
