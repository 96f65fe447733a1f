#include "Compare.h"

#include "bake/output/BakeDump.h"
#include "bake/Scene.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"

#include <fmt/format.h>

#include <bit>
#include <optional>
#include <cstring>
#include <memory>

namespace penumbra {
namespace {

/// Receivers compared per step: dumps of millions of receivers are read in pieces of this many
/// rows, so the comparison holds a few MB whatever the dump size.
constexpr uint64_t kRowsPerStep = 1 << 16;

const char* quantityName(RuleQuantity q) {
    switch (q) {
        case RuleQuantity::SampleInPlane: return "sample_in_plane";
        case RuleQuantity::Band: return "band";
        case RuleQuantity::Edge: return "edge";
        default: return "none";
    }
}

std::unique_ptr<TieClassifier> makeClassifier(const std::string& scenePath, const ReceiverEpsilon& epsilon) {
    const SceneDesc scene = loadScene(scenePath);
    TriangleSourcePtr source = openSceneGeometry(scene);
    // The scene's alpha table: its max_distance ids carry the limits the classifier tests.
    return std::make_unique<TieClassifier>(readAll(*source), epsilon, TieClassifier::kDefaultUlps, scene.options.alphaTable);
}

void checkSameInputs(const BakeDumpReader& a, const BakeDumpReader& b, const std::string& dirA, const std::string& dirB) {
    if (a.receivers() != b.receivers())
        fail(dirB, "receivers.npy differs from {}: the dumps are not of the same receivers", dirA);
    if (a.sets() != b.sets() || a.samples() != b.samples() || a.rawSamples() != b.rawSamples())
        fail(dirB, "samples.npy differs from {}: the dumps are not of the same light samples", dirA);
    if (a.epsilon().relative != b.epsilon().relative || a.epsilon().length != b.epsilon().length)
        fail(dirB, "rule.json differs from {}: the dumps were not baked with the same receiver epsilon", dirA);
}

}  // namespace

CompareResult compareDumps(const CompareOptions& o) {
    BakeDumpReader a(o.dirA), b(o.dirB);
    checkSameInputs(a, b, o.dirA, o.dirB);
    CompareResult r;
    r.receivers = a.receivers(), r.samples = a.samples(), r.relations = r.receivers * r.samples;
    const uint64_t words = a.maskWords();

    std::unique_ptr<TieClassifier> classifier;
    if (!o.scenePath.empty()) classifier = makeClassifier(o.scenePath, a.epsilon()), r.classified = true;
    std::string csv = "receiver,sample,blocked_in,rule_blocks,tie,quantity,triangle,edge,value,threshold,tolerance\n";
    uint64_t listed = 0;

    std::vector<DumpReceiver> recA, recB;
    std::vector<uint64_t> ma, mb;
    for (uint64_t first = 0; first < r.receivers; first += kRowsPerStep) {
        const uint64_t rows = std::min(kRowsPerStep, r.receivers - first);
        a.next(rows, recA, ma), b.next(rows, recB, mb);
        if (std::memcmp(a.rawReceivers().data(), b.rawReceivers().data(), a.rawReceivers().size() * sizeof(float)) != 0)
            fail(o.dirB, "receivers.npy differs from {}: the dumps are not of the same receivers", o.dirA);
        for (uint64_t i = 0; i < rows; ++i)
            for (uint64_t w = 0; w < words; ++w) {
                const uint64_t x = ma[i * words + w], y = mb[i * words + w];
                r.blockedA += std::popcount(x), r.blockedB += std::popcount(y);
                r.onlyA += std::popcount(x & ~y), r.onlyB += std::popcount(y & ~x);
                // Without --scene the mismatches are still listed, with no verdict (the CSV's
                // verdict columns empty): a list and a CSV of only a header hid them.
                if (!classifier && listed >= o.list && o.mismatchesCsv.empty()) continue;
                for (uint64_t diff = x ^ y; diff; diff &= diff - 1) {
                    const uint64_t k = w * 64 + uint64_t(std::countr_zero(diff));
                    const DumpReceiver& rec = recA[i];
                    const bool inA = (x >> (k % 64)) & 1;
                    std::optional<RelationVerdict> v;
                    if (classifier) {
                        const glm::dvec4 s = a.sample(rec.sampleSet, k);
                        v = classifier->classify(glm::dvec3(s), s.w, rec.position);
                        if (v->tie) ++r.ties, ++r.tiesByQuantity[quantityName(v->quantity)];
                    }
                    if (listed < o.list) {
                        fmt::print("mismatch receiver {} sample {} (set {}): blocked in {} only{}\n", first + i, k, rec.sampleSet,
                                   inA ? "A" : "B", v ? ": " + v->describe() : std::string(" (give --scene for a verdict)"));
                        ++listed;
                    }
                    if (o.mismatchesCsv.empty()) continue;
                    csv += fmt::format("{},{},{},", first + i, k, inA ? "A" : "B");
                    csv += v ? fmt::format("{},{},{},{},{},{:.17g},{:.17g},{:.17g}\n", int(v->ruleBlocks), int(v->tie),
                                           quantityName(v->quantity), v->triangle, v->edge, v->value, v->threshold, v->tolerance)
                             : std::string(",,,,,,,\n");
                }
            }
    }
    if (!o.mismatchesCsv.empty())
        writeFileAtomically(o.mismatchesCsv, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(csv.data()), csv.size()));
    return r;
}

}  // namespace penumbra
