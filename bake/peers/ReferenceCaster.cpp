#include "bake/peers/ReferenceCaster.h"

#include "bake/rule/AlphaRule.h"
#include "bake/cast/SceneCaster.h"
#include "stream/Translucency.h"

#include <tbb/parallel_for.h>

namespace penumbra {

VisibilityMasks castReference(const LightSamples& samples, const ReceiverSet& receivers,
                              std::span<const uint32_t> sampleSetOf, std::span<const Triangle> triangles,
                              const ReceiverEpsilon& epsilon, const std::function<void(uint64_t)>& progress,
                              const AlphaTable& alpha) {
    std::vector<BlockerTriangle> blockers;
    blockers.reserve(triangles.size());
    for (const Triangle& t : triangles) {
        BlockerTriangle b = BlockerTriangle::from(t);
        // "cast_shadows": false and translucent triangles block nothing.
        if (b.valid && blocksAsOpaque(t.flags)) blockers.push_back(b);
    }
    VisibilityMasks masks(receivers.size(), samples.groupCount());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, receivers.size(), 16), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t r = range.begin(); r != range.end(); ++r) {
            const glm::dvec3 p(receivers.position[r]);
            const int set = int(sampleSetOf[r]);
            for (int k = 0; k < samples.groupCount(); ++k) {
                const LightSampleGroup& g = samples.groups[k];
                const double w = samples.w(g.light);
                uint64_t word = 0;
                for (uint32_t j = 0; j < g.count; ++j) {
                    const glm::dvec3 l(samples.position(set, int(g.first + j)));
                    for (const BlockerTriangle& t : blockers)
                        if (blocksWithAlpha(l, w, p, t, epsilon, alpha)) {
                            word |= 1ull << j;
                            break;
                        }
                }
                masks.row(r)[k] = word;
            }
        }
        if (progress) progress(range.size());
    });
    return masks;
}

}  // namespace penumbra

namespace penumbra {
namespace {

const CasterRegistration kReference{{"reference",
                                     {.holdsScene = true, .summary = "every segment against every triangle: a correctness oracle, slow"},
                                     [](const CastContext& c) {
                                         return std::make_unique<SceneCaster>(
                                             c, "reference",
                                             [eps = receiverEpsilonOf(c.options), &samples = c.samples, &options = c.options](const ReceiverSet& targets, std::span<const uint32_t> sets,
                                                                                       std::span<const Triangle> all, const auto& progress) {
                                                 return castReference(samples, targets, sets, all, eps, progress, alphaTableOf(options));
                                             });
                                     },
                                     [](uint64_t triangles, uint64_t, const LightSamples&, const nlohmann::json&) {
                                         return triangles * (sizeof(Triangle) + sizeof(BlockerTriangle));
                                     },
                                     nullptr}};

}  // namespace
}  // namespace penumbra
