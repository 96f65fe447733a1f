#include "Compare.h"

#include "bake/BlockingRule.h"
#include "bake/Scene.h"
#include "stream/Error.h"
#include "stream/Npy.h"

#include <bit>
#include <cstring>
#include <filesystem>

namespace penumbra {
namespace {

struct Dump {
    NpyArray receivers, samples, masks;
};

Dump loadDump(const std::string& dir) {
    auto path = [&](const char* name) { return (std::filesystem::path(dir) / name).string(); };
    Dump d{readNpy(path("receivers.npy")), readNpy(path("samples.npy")), readNpy(path("masks.npy"))};
    if (d.receivers.dtype != "<f4" || d.receivers.shape.size() != 2 || d.receivers.shape[1] != 7)
        fail(path("receivers.npy"), "expected float32 N x 7");
    if (d.samples.dtype != "<f4" || d.samples.shape.size() != 3 || d.samples.shape[2] != 3)
        fail(path("samples.npy"), "expected float32 S x K x 3");
    uint64_t n = d.receivers.shape[0], k = d.samples.shape[1];
    if (d.masks.dtype != "<u8" || d.masks.shape.size() != 2 || d.masks.shape[0] != n || d.masks.shape[1] != (k + 63) / 64)
        fail(path("masks.npy"), "expected uint64 {} x {} to match receivers.npy and samples.npy", n, (k + 63) / 64);
    return d;
}

}  // namespace

CompareResult compareDumps(const std::string& dirA, const std::string& dirB, const std::string& scenePath) {
    Dump a = loadDump(dirA), b = loadDump(dirB);
    if (a.receivers.shape != b.receivers.shape || a.receivers.data != b.receivers.data)
        fail(dirB, "receivers.npy differs from {}: the dumps are not of the same receivers", dirA);
    if (a.samples.shape != b.samples.shape || a.samples.data != b.samples.data)
        fail(dirB, "samples.npy differs from {}: the dumps are not of the same light samples", dirA);

    CompareResult r;
    r.receivers = a.receivers.shape[0];
    r.samples = a.samples.shape[1];
    r.relations = r.receivers * r.samples;
    const uint64_t words = (r.samples + 63) / 64;
    auto maskA = reinterpret_cast<const uint64_t*>(a.masks.data.data());
    auto maskB = reinterpret_cast<const uint64_t*>(b.masks.data.data());
    auto rec = reinterpret_cast<const float*>(a.receivers.data.data());
    auto smp = reinterpret_cast<const float*>(a.samples.data.data());

    std::vector<BlockerTriangle> blockers;
    double epsilon = 0;
    if (!scenePath.empty()) {
        SceneDesc scene = loadScene(scenePath);
        epsilon = scene.options.epsilon;
        TriangleSourcePtr source = openSceneGeometry(scene);
        for (const Triangle& t : readAll(*source))
            if (BlockerTriangle bt = BlockerTriangle::from(t); bt.valid) blockers.push_back(bt);
        r.classified = true;
    }

    for (uint64_t i = 0; i < r.receivers; ++i)
        for (uint64_t w = 0; w < words; ++w) {
            uint64_t x = maskA[i * words + w], y = maskB[i * words + w];
            r.blockedA += std::popcount(x), r.blockedB += std::popcount(y);
            r.onlyA += std::popcount(x & ~y), r.onlyB += std::popcount(y & ~x);
            if (!r.classified) continue;
            for (uint64_t diff = x ^ y; diff; diff &= diff - 1) {
                uint64_t k = w * 64 + uint64_t(std::countr_zero(diff));
                const float* p = rec + i * 7;
                uint64_t set = uint64_t(p[6]);
                const float* s = smp + (set * r.samples + k) * 3;
                glm::dvec3 recv(p[0], p[1], p[2]), light(s[0], s[1], s[2]);
                for (const BlockerTriangle& t : blockers)
                    if (isTie(light, recv, t, epsilon, 1e-4)) {
                        ++r.ties;
                        break;
                    }
            }
        }
    return r;
}

}  // namespace penumbra
