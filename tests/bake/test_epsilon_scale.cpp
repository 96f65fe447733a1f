// The receiver epsilon is relative to the scene: a uniformly scaled scene gives the same masks at
// every scale from 1e-4 to 1e4 (bit for bit at powers of two, up to classified ties otherwise),
// contact shadows included.

#include "CliRunner.h"
#include "TestScenes.h"
#include "TestSupport.h"

#include "bake/output/BakeDump.h"
#include "bake/rule/TieClassifier.h"
#include "stream/util/Npy.h"
#include "stream/ObjReader.h"

#include <catch2/catch.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <fstream>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// A floor, a soup of blockers and a thin slab 0.02 above the floor (contact shadows 1/200 of the
/// scene's size), and receivers on the floor and the blockers.
struct ScaledScene {
    std::vector<Triangle> tris;
    ReceiverSet receivers;
    ScaledScene() {
        soupOverFloor(tris, receivers);
        addQuad(tris, {1, 0.02f, 1}, {2, 0.02f, 1}, {2, 0.02f, 2}, {1, 0.02f, 2});
        addReceiversOnTriangles(receivers, {tris.back()}, 51, 50);
        for (int i = 0; i < 100; ++i) {  // right under the slab's edge
            receivers.position.push_back({0.9f + 0.002f * i, 0.0f, 1.5f});
            receivers.normal.push_back({0, 1, 0});
        }
    }

    /// Writes the scene scaled by @p s into @p dir (OBJ with round-tripping floats) and bakes it.
    std::string bake(const ScratchDir& dir, double s, const std::string& name) const {
        std::ofstream obj(dir / (name + ".obj"));
        for (const Triangle& t : tris) {
            for (const glm::vec3& v : t.v) obj << fmt::format("v {:.9g} {:.9g} {:.9g}\n", float(v.x * s), float(v.y * s), float(v.z * s));
            obj << "f -3 -2 -1\n";
        }
        obj.close();
        std::vector<float> pts;
        for (size_t i = 0; i < receivers.size(); ++i) {
            const glm::vec3 p = receivers.position[i], n = receivers.normal[i];
            pts.insert(pts.end(), {float(p.x * s), float(p.y * s), float(p.z * s), n.x, n.y, n.z});
        }
        uint64_t shape[2] = {receivers.size(), 6};
        writeNpy(dir / (name + ".npy"), "<f4", shape, pts.data(), pts.size() * sizeof(float));
        const nlohmann::json scene = {
            {"geometry", {{{"type", "obj"}, {"path", name + ".obj"}}}},
            {"lights", {{{"type", "rect"}, {"center", {0.3 * s, 4 * s, 0.2 * s}}, {"u", {1.5 * s, 0, 0}}, {"v", {0, 0, 1.5 * s}},
                         {"samples", 64}, {"sample_sets", 4}}}},
            {"receivers", {{"type", "points"}, {"path", name + ".npy"}}},
            {"output", name + "-vis.npy"}};
        std::ofstream(dir / (name + ".json")) << scene.dump();
        RunResult r = runPenumbra("bake " + (dir / (name + ".json")) + " -q --dump " + (dir / name));
        INFO(r.err);
        REQUIRE(r.exitCode == 0);
        return dir / name;
    }
};

}  // namespace

TEST_CASE("a uniformly scaled scene has the same masks at every scale", "[epsilon][exact]") {
    ScratchDir dir("scale");
    const ScaledScene scene;
    const std::string unit = scene.bake(dir, 1.0, "s1");
    const NpyArray masks = readNpy(unit + "/masks.npy");
    // The slab's contact shadow is there at scale 1: some receiver right under its edge is blocked.
    const auto* m = reinterpret_cast<const uint64_t*>(masks.data.data());
    const uint64_t words = masks.shape[1], n = masks.shape[0];
    uint64_t underSlab = 0;
    for (uint64_t r = n - 100; r < n; ++r)
        for (uint64_t w = 0; w < words; ++w) underSlab += __builtin_popcountll(m[r * words + w]);
    CHECK(underSlab > 1000);

    for (int k : {-13, -7, 7, 13}) {  // 1.2e-4, 7.8e-3, 128, 8192: scaling by a power of two is exact
        INFO("scale 2^" << k);
        const std::string scaled = scene.bake(dir, std::ldexp(1.0, k), fmt::format("p{}", k + 20));
        CHECK(readNpy(scaled + "/masks.npy").data == masks.data);
    }
    for (double s : {1e-4, 1e4}) {  // rounding differs from scale 1: mismatches must be ties there
        INFO("scale " << s);
        const std::string scaled = scene.bake(dir, s, s < 1 ? "small" : "large");
        BakeDumpReader dump(scaled);
        std::vector<DumpReceiver> rec;
        std::vector<uint64_t> sm;
        dump.next(dump.receivers(), rec, sm);
        const std::vector<Triangle> tris = readAll(*openObj(dir / (s < 1 ? "small.obj" : "large.obj")));
        const TieClassifier classifier(tris, dump.epsilon());
        uint64_t mismatches = 0;
        for (uint64_t r = 0; r < n; ++r)
            for (uint64_t w = 0; w < words; ++w)
                for (uint64_t diff = m[r * words + w] ^ sm[r * words + w]; diff; diff &= diff - 1) {
                    const uint64_t k = w * 64 + uint64_t(__builtin_ctzll(diff));
                    const glm::dvec4 l = dump.sample(rec[r].sampleSet, k);
                    const RelationVerdict v = classifier.classify(glm::dvec3(l), l.w, rec[r].position);
                    INFO("receiver " << r << " sample " << k << ": " << v.describe());
                    CHECK(v.tie);
                    ++mismatches;
                }
        CHECK(mismatches <= n * dump.samples() / 1000);
    }
}
