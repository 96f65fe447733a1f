#pragma once
// Checks shared by the tests of the other methods (ssv, penumbra-map, hh): exact masks against
// the reference up to classified ties, and visible fractions against an analytic profile.

#include "TestScenes.h"

#include "bake/methods/SsvCaster.h"
#include "bake/rule/TieClassifier.h"

#include <catch2/catch.hpp>

#include <string>
#include <vector>

namespace penumbra::test {

/// Relations where two mask sets differ, and how many of them the tie classifier calls ties.
struct TieCount {
    uint64_t mismatches = 0, ties = 0;
};

inline TieCount classifyMismatches(const LightSamples& samples, const ReceiverSet& receivers,
                                   const std::vector<uint32_t>& sets, const std::vector<Triangle>& triangles,
                                   const VisibilityMasks& a, const VisibilityMasks& b, const ReceiverEpsilon& eps,
                                   std::shared_ptr<const AlphaTable> alpha = AlphaTable::builtin()) {
    TieCount count;
    const TieClassifier classifier(triangles, eps, TieClassifier::kDefaultUlps, std::move(alpha));
    for (size_t r = 0; r < receivers.size(); ++r)
        for (int k = 0; k < a.groups; ++k)
            for (uint64_t diff = a.row(r)[k] ^ b.row(r)[k]; diff; diff &= diff - 1) {
                const int j = __builtin_ctzll(diff);
                const LightSampleGroup& g = samples.groups[k];
                const glm::dvec3 l(samples.position(int(sets[r]), int(g.first) + j)), p(receivers.position[r]);
                const RelationVerdict v = classifier.classify(l, samples.w(g.light), p);
                UNSCOPED_INFO("receiver " << r << " sample " << g.first + j << " reference " << (a.row(r)[k] >> j & 1)
                                          << ": " << v.describe());
                ++count.mismatches;
                count.ties += v.tie;
            }
    return count;
}

/// ssv against the reference: every mismatch a tie of the rule, and ties rare. Cut-outs name
/// the alpha maps of @p alpha.
inline void requireSsvMatchesReference(const std::string& scene, const std::vector<LightDesc>& lights,
                                       const ReceiverSet& receivers, const std::vector<Triangle>& triangles,
                                       int groupSize = 64, const ReceiverEpsilon& eps = receiverEpsilonOf(CastOptions()),
                                       std::shared_ptr<const AlphaTable> alpha = AlphaTable::builtin()) {
    LightSamples samples = generateLightSamples(lights, groupSize, 7);
    std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    VisibilityMasks reference = castReference(samples, receivers, sets, triangles, eps, {}, *alpha);
    INFO(scene << ": " << reference.blockedCount() << " blocked of " << receivers.size() * samples.sampleCount);
    REQUIRE(reference.blockedCount() > 0);
    REQUIRE(reference.blockedCount() < uint64_t(receivers.size()) * samples.sampleCount);
    SsvStats stats;
    SsvOptions options;
    options.alpha = alpha.get();
    VisibilityMasks ssv = castSsv(samples, receivers, sets, triangles, eps, options, &stats);
    const TieCount c = classifyMismatches(samples, receivers, sets, triangles, reference, ssv, eps, alpha);
    INFO("mismatches " << c.mismatches << ", ties " << c.ties << ", silhouette terms " << stats.silhouetteEdges
                       << ", band terms " << stats.bandEdges << ", retries " << stats.referenceRetries << ", fallbacks "
                       << stats.fallbackFrustums << ", alpha tests " << stats.alphaTests);
    CHECK(c.mismatches == c.ties);
    CHECK(double(c.mismatches) <= 1e-4 * double(receivers.size()) * samples.sampleCount);
}

}  // namespace penumbra::test
