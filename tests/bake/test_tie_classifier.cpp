// The tie classifier of `penumbra compare`: ties are relations within float roundoff of one of the
// rule's thresholds, nothing else. Every planted error in a real dump is reported as real.

#include "CliRunner.h"
#include "TestScenes.h"
#include "TestSupport.h"

#include "bake/rule/TieClassifier.h"
#include "stream/util/Npy.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <set>

using namespace penumbra;
using namespace penumbra::test;

namespace {

const ReceiverEpsilon kEps{1e-5, 1.0};

/// A floor and a blocker quad above it.
std::vector<Triangle> floorAndQuad() {
    std::vector<Triangle> t;
    addQuad(t, {-4, 0, -4}, {4, 0, -4}, {4, 0, 4}, {-4, 0, 4});
    addQuad(t, {-0.5f, 1, -0.5f}, {0.5f, 1, -0.5f}, {0.5f, 1, 0.5f}, {-0.5f, 1, 0.5f});
    return t;
}

}  // namespace

TEST_CASE("classifier: a receiver on its own triangle is not a tie, a segment through an edge is", "[tie]") {
    const TieClassifier c(floorAndQuad(), kEps);
    // A floor receiver under the quad (off its diagonal): robustly blocked, by the quad.
    RelationVerdict v = c.classify({0.1, 4, -0.2}, 1.0, {0.1, 0, -0.2});
    CHECK(v.ruleBlocks);
    CHECK_FALSE(v.tie);
    CHECK(v.triangle >= 2);  // one of the quad's triangles, not the floor
    // Lit and far from every edge: a real non-block, although the receiver lies on the floor.
    v = c.classify({3, 4, 3}, 1.0, {3, 0, 3});
    CHECK_FALSE(v.ruleBlocks);
    CHECK_FALSE(v.tie);
    CHECK(v.quantity == RuleQuantity::None);
    // Through the diagonal the two triangles share: each alone is within roundoff of missing it, so
    // a non-watertight float test (Embree's) may miss both: a tie.
    CHECK(c.classify({0, 4, 0}, 1.0, {0, 0, 0}).tie);
    // The segment passes exactly through the quad's edge x = 0.5: a tie of the edge test.
    v = c.classify({0.5, 4, 0.2}, 1.0, {0.5, 0, 0.2});
    CHECK(v.tie);
    CHECK(v.quantity == RuleQuantity::Edge);
    CHECK(std::abs(v.value) <= v.tolerance);
    // The same for a direction: a sun straight above.
    v = c.classify({0, 1, 0}, 0.0, {0.5, 0, -0.1});
    CHECK(v.tie);
    CHECK(v.quantity == RuleQuantity::Edge);
    v = c.classify({0, 1, 0}, 0.0, {0.4, 0, -0.1});
    CHECK(v.ruleBlocks);
    CHECK_FALSE(v.tie);
    // 1e-4 inside the edge is far beyond float roundoff: not a tie any more.
    v = c.classify({0.5 - 1e-4, 4, 0.2}, 1.0, {0.5 - 1e-4, 0, 0.2});
    CHECK(v.ruleBlocks);
    CHECK_FALSE(v.tie);
}

TEST_CASE("classifier: far from the origin, ties stay as narrow as T's roundoff relative to the receiver", "[tie]") {
    // A mesh of 5 cm triangles 1 m above a floor receiver, at (1e4, 0, -1e4), where a float is
    // 1e-3 apart. A segment through a triangle 5 mm from its nearest edge is robustly blocked
    // (32 ulps of the coordinates, the old tolerance, were 2 cm: every relation was a tie, and a
    // dump with every mask zeroed compared as ties), one 0.1 mm from an edge is a tie, and one
    // 5 mm outside the mesh is robustly not blocked.
    const float X = 1e4f, Z = -1e4f, h = 0.05f;
    std::vector<Triangle> mesh;
    for (int i = 0; i < 8; ++i)
        for (int k = 0; k < 8; ++k) {
            const float x0 = X + h * float(i), z0 = Z + h * float(k);
            addQuad(mesh, {x0, 1, z0}, {x0 + h, 1, z0}, {x0 + h, 1, z0 + h}, {x0, 1, z0 + h});
        }
    const TieClassifier c(mesh, ReceiverEpsilon{1e-5, 1.5e4});
    const glm::dvec3 r{double(X) + 0.2, 0, double(Z) + 0.2};  // under the mesh
    auto through = [&](double dx, double dz) {  // the segment from r straight up through (r.x + dx, 1, r.z + dz)
        return c.classify(glm::dvec3(r.x + 4 * dx, 4, r.z + 4 * dz), 1.0, r);
    };
    // r's column meets the mesh at a cell corner (0.2 = 4 cells); 0.0125 inward is a quarter cell.
    const RelationVerdict inside = through(0.0125, 0.0325);
    CHECK(inside.ruleBlocks);
    CHECK_FALSE(inside.tie);
    const RelationVerdict nearEdge = through(0.0125, 0.0001);
    CHECK(nearEdge.tie);
    const RelationVerdict outside = c.classify(glm::dvec3(double(X) - 0.005, 4, r.z), 1.0, glm::dvec3(double(X) - 0.005, 0, r.z));
    INFO(outside.describe());
    CHECK_FALSE(outside.ruleBlocks);
    CHECK_FALSE(outside.tie);
}

TEST_CASE("classifier: the epsilon band and a sample in the blocker's plane", "[tie]") {
    std::vector<Triangle> quad;
    addQuad(quad, {-1, 1, -1}, {1, 1, -1}, {1, 1, 1}, {-1, 1, 1});
    const TieClassifier c(quad, kEps);
    // A receiver eps(r) below the quad (eps = 1e-5 here), lit from above: within roundoff of the band.
    RelationVerdict v = c.classify({0.1, 3, 0.1}, 1.0, glm::dvec3(0.1, 1 - 1e-5, 0.1));
    CHECK(v.tie);
    CHECK(v.quantity == RuleQuantity::Band);
    // A receiver on the quad (distance 0): robustly not blocked by it.
    v = c.classify({0.1, 3, 0.1}, 1.0, {0.1, 1, 0.1});
    CHECK_FALSE(v.tie);
    // A sample in the quad's plane: a tie of the sample's side.
    v = c.classify({0.2, 1, 0.3}, 1.0, {0.1, 0, 0.1});
    CHECK(v.tie);
    CHECK(v.quantity == RuleQuantity::SampleInPlane);
    // A sun direction parallel to the quad, from a receiver below it: nothing can flip.
    v = c.classify({1, 0, 0}, 0.0, {0.1, 0, 0.1});
    CHECK_FALSE(v.ruleBlocks);
    CHECK_FALSE(v.tie);
}

namespace {

/// Bakes @p scene with --dump into @p dump and returns the dump's mask file.
void bakeDump(const ScratchDir& dir, const std::string& scene, const std::string& dump) {
    RunResult r = runPenumbra("bake " + (dir / scene) + " -q -o " + (dir / (dump + ".exr")) + " --dump " + (dir / dump));
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
}

/// Copies dump @p from to @p to with @p flips relations flipped at random (seeded), including
/// receivers on the floor, and returns how many were flipped.
void plantFlips(const ScratchDir& dir, const std::string& from, const std::string& to, int flips, uint64_t seed) {
    std::filesystem::copy(dir / from, dir / to);
    NpyArray masks = readNpy(dir / (from + "/masks.npy"));
    NpyArray samples = readNpy(dir / (from + "/samples.npy"));
    const uint64_t n = masks.shape[0], words = masks.shape[1], k = samples.shape[1];
    auto* m = reinterpret_cast<uint64_t*>(masks.data.data());
    Rng rng(seed);
    std::set<std::pair<uint64_t, uint64_t>> planted;
    while (planted.size() < size_t(flips)) planted.insert({rng.next() % n, rng.next() % k});
    for (auto [r, s] : planted) m[r * words + s / 64] ^= 1ull << (s % 64);
    std::filesystem::remove(dir / (to + "/masks.npy"));
    writeNpy(dir / (to + "/masks.npy"), masks);
}

}  // namespace

TEST_CASE("compare reports every planted flip in a real dump as a real mismatch, exit 3", "[tie][cli]") {
    ScratchDir dir("ties");
    const nlohmann::json geometry = {{{"type", "grid"}, {"size", 2}, {"cells", 6}, {"levels", 2}, {"height", 0.6},
                                      {"spacing", 0.4}, {"floor_size", 5}}};
    const nlohmann::json camera = {{"type", "camera"}, {"eye", {0, 3, 3.5}}, {"target", {0, 0.3, 0}}, {"up", {0, 1, 0}},
                                   {"fov_deg", 45}, {"width", 64}, {"height", 48}};
    const nlohmann::json rect = {{"type", "rect"}, {"center", {0, 3, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}, {"samples", 64}};
    const nlohmann::json sun = {{"type", "sun"}, {"direction", {0.3, -1, 0.2}}, {"angular_diameter_deg", 2}, {"samples", 64}};
    // A points dump: receivers on the floor (where a loose tie test would accept everything).
    std::vector<float> pts;
    Rng rng(3);
    for (int i = 0; i < 400; ++i) pts.insert(pts.end(), {float(rng.uniform(-2, 2)), 0.0f, float(rng.uniform(-2, 2)), 0, 1, 0});
    uint64_t shape[2] = {400, 6};
    writeNpy(dir / "pts.npy", "<f4", shape, pts.data(), pts.size() * sizeof(float));
    const nlohmann::json points = {{"type", "points"}, {"path", "pts.npy"}};
    int index = 0;
    for (const nlohmann::json& receivers : {camera, points})
        for (const nlohmann::json& light : {rect, sun}) {
            const std::string name = fmt::format("s{}", index++);
            nlohmann::json s = {{"geometry", geometry}, {"lights", {light}}, {"receivers", receivers}, {"output", name + ".exr"}};
            if (receivers["type"] == "points") s["output"] = name + ".npy";
            std::ofstream(dir / (name + ".json")) << s.dump();
            bakeDump(dir, name + ".json", name);
            RunResult same = runPenumbra("compare " + (dir / name) + " " + (dir / name) + " --scene " + (dir / (name + ".json")));
            CHECK(same.exitCode == 0);
            plantFlips(dir, name, name + "-flipped", 40, 11 + index);
            RunResult r = runPenumbra("compare " + (dir / name) + " " + (dir / (name + "-flipped")) + " --scene " +
                                      (dir / (name + ".json")) + " --list 3");
            INFO(name << ": " << r.out << r.err);
            CHECK(r.exitCode == 3);
            CHECK_THAT(r.out, Catch::Contains("ties 0\n") && Catch::Contains("unexplained 40\n"));
            CHECK_THAT(r.out, Catch::Contains("mismatch receiver") && Catch::Contains("real:"));
        }
}

TEST_CASE("compare refuses a mask file with bits above the dump's samples", "[tie][cli]") {
    // A 65-sample light: the second word of each row holds one sample. A bit above it named a
    // sample that does not exist, and with --scene was classified from beyond samples.npy.
    ScratchDir dir("ties-padding");
    const nlohmann::json s = {{"geometry", {{{"type", "grid"}, {"size", 2}, {"cells", 4}, {"levels", 1}, {"floor_size", 5}}}},
                              {"lights", {{{"type", "rect"}, {"center", {0, 3, 0}}, {"u", {1, 0, 0}}, {"v", {0, 0, 1}}, {"samples", 65}}}},
                              {"receivers", {{"type", "camera"}, {"eye", {0, 3, 3.5}}, {"target", {0, 0, 0}}, {"width", 16}, {"height", 12}}},
                              {"output", "s.exr"}};
    std::ofstream(dir / "s.json") << s.dump();
    bakeDump(dir, "s.json", "a");
    std::filesystem::copy(dir / "a", dir / "b");
    NpyArray masks = readNpy(dir / "a/masks.npy");
    REQUIRE(masks.shape[1] == 2);
    reinterpret_cast<uint64_t*>(masks.data.data())[5 * 2 + 1] |= 1ull << 40;  // receiver 5, "sample 104"
    std::filesystem::remove(dir / "b/masks.npy");
    writeNpy(dir / "b/masks.npy", masks);
    for (const std::string& scene : {std::string(), " --scene " + (dir / "s.json")}) {
        RunResult r = runPenumbra("compare " + (dir / "a") + " " + (dir / "b") + scene);
        INFO(r.out << r.err);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.err, Catch::Contains("b/masks.npy: receiver 5: bits set above its 65 samples"));
    }
}
