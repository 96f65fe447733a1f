// Closed casters keep every shadow for receivers beside a closed solid, within the rule's epsilon
// of a light-facing face's plane (ClosedExemptions.h): a segment that enters through a skipped
// face and leaves through that face, which does not block so near the receiver's plane, is still
// blocked as the reference blocks it.

#include "CliRunner.h"
#include "TestScenes.h"
#include "TestSupport.h"

#include "bake/cast/ClosedExemptions.h"
#include "bake/cast/ClosedSolids.h"
#include "bake/cast/PenumbraVolume.h"
#include "procedural/BoxFaces.h"
#include "stream/util/Npy.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <fstream>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// The twelve triangles of the box [lo, hi], wound outward, marked closed.
std::vector<Triangle> closedBox(glm::vec3 lo, glm::vec3 hi) {
    auto corner = [&](int c) { return glm::vec3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z); };
    std::vector<Triangle> out;
    for (const auto& f : kBoxFaceTriangles) out.push_back({{corner(f[0]), corner(f[1]), corner(f[2])}, kTriangleClosed});
    out[0].flags |= kTriangleSolidStart;
    return out;
}

/// A thin rect light high above x = 0, straddling the plane of the box's +x face.
LightDesc straddlingLight() { return rectLight({0.004, 10, 0}, {0.02, 0, 0}, {0, 0, 0.5}, 256, 4); }

/// 200 receivers under the box [-1, 0] x [1, 2] x [-1, 1], each 0.1..0.9 eps behind the plane x = 0
/// of its +x face, and one far receiver that makes L = 100, so eps(r) = 1e-5 * 100 = 1e-3.
std::vector<glm::vec3> besideThePlane() {
    std::vector<glm::vec3> points;
    uint32_t state = 12345;
    auto next = [&] { return (state = state * 1664525u + 1013904223u) / 4294967296.0; };
    for (int i = 0; i < 200; ++i) points.push_back({float(-(0.1 + 0.8 * next()) * 1e-3), 0.0f, float(-0.9 + 1.8 * next())});
    points.push_back({100, 0, 0});
    return points;
}

}  // namespace

TEST_CASE("closed exemptions: a receiver beside a solid, within epsilon behind a face's plane", "[closed][exact]") {
    const std::vector<Triangle> box = closedBox({-1, 1, -1}, {0, 2, 1});
    const LightSamples samples = generateLightSamples({straddlingLight()}, 64, 7);
    const std::span<const glm::vec3> set0(samples.positions.data(), size_t(samples.sampleCount));
    const ReceiverEpsilon epsilon{1e-5, 100.0};  // eps(r) = 1e-3
    // The +x face: its two triangles have normal +x.
    int faces = 0;
    bool belowMarked = false;
    for (const Triangle& t : box) {
        const BlockerTriangle g = BlockerTriangle::from(t);
        if (g.plane.n.x < 0.5) continue;
        ++faces;
        const PenumbraVolume volume = makePenumbraVolume(samples.lightBounds[0], g);
        // Below the box, 0.5 eps behind the plane: a segment up to the light leaves through this
        // face after entering through the bottom one.
        const glm::dvec3 below(-5e-4, 0, 0);
        // On the face, and just under it inside the box: never lost.
        const glm::dvec3 onFace = (g.v[0] + g.v[1] + g.v[2]) / 3.0;
        const glm::dvec3 underFace = onFace - glm::dvec3(5e-4, 0, 0);
        // Not for a light whose samples all lie behind the plane x = 0: none leaves through it.
        std::vector<glm::vec3> behind(set0.begin(), set0.end());
        for (glm::vec3& p : behind) p.x = -0.01f - std::abs(p.x);
        CHECK_FALSE(closedFaceMayFailAt(g, volume, below, epsilon, behind, 1.0));
        belowMarked = belowMarked || closedFaceMayFailAt(g, volume, below, epsilon, set0, 1.0);
        CHECK_FALSE(closedFaceMayFailAt(g, volume, onFace, epsilon, set0, 1.0));
        CHECK_FALSE(closedFaceMayFailAt(g, volume, underFace, epsilon, set0, 1.0));
        CHECK_FALSE(closedFaceMayFailAt(g, volume, {5e-4, 0, 0}, epsilon, set0, 1.0));   // in front of the plane
        // On the plane beside the solid (the coplanar face of a neighbour): a segment from it runs
        // within roundoff of the plane to the solid's edge, a tie of the entry face's edge.
        CHECK_FALSE(closedFaceMayFailAt(g, volume, {0, 0, 0.25}, epsilon, set0, 1.0));
        CHECK_FALSE(closedFaceMayFailAt(g, volume, {-5e-3, 0, 0}, epsilon, set0, 1.0));  // beyond eps: the face blocks
    }
    CHECK(faces == 2);
    CHECK(belowMarked);

    // Over the whole box and receivers: every receiver by the plane is marked, the far one is not,
    // and a subset of the receivers gets the same marks (marks are per receiver).
    const std::vector<glm::vec3> points = besideThePlane();
    const ReceiverSet receivers = receiversFacingUp(points);
    CastOptions options;
    options.epsilonLength = 100.0;
    std::vector<uint32_t> all(points.size()), odd;
    for (uint32_t i = 0; i < all.size(); ++i) all[i] = i;
    for (uint32_t i = 1; i < all.size(); i += 2) odd.push_back(i);
    const std::vector<uint32_t> sets(points.size(), 0);
    ClosedExemptionFinder finder(samples, receivers, sets, all, options);
    finder.scan(box);
    const std::vector<uint32_t> marked = finder.exempt();
    CHECK(marked.size() == 200);
    CHECK(marked.back() == 199);
    CHECK(finder.facesTested() == 4);  // the top and +x faces: the others face away from the light
    ClosedExemptionFinder subset(samples, receivers, sets, odd, options);
    subset.scan(box);
    std::vector<uint32_t> expected;
    for (uint32_t r : marked)
        if (r % 2) expected.push_back(r);
    CHECK(subset.exempt() == expected);
    // Not closed: nothing to mark.
    std::vector<Triangle> open = box;
    for (Triangle& t : open) t.flags = 0;
    ClosedExemptionFinder none(samples, receivers, sets, all, options);
    none.scan(open);
    CHECK(none.exempt().empty());
}

TEST_CASE("closed casters keep the shadow of a box on receivers within epsilon of its face's plane", "[closed][exact]") {
    ScratchDir dir("closed-exempt");
    std::vector<float> pts;
    for (const glm::vec3& p : besideThePlane()) pts.insert(pts.end(), {p.x, p.y, p.z, 0, 1, 0});
    const uint64_t shape[2] = {pts.size() / 6, 6};
    writeNpy(dir / "pts.npy", "<f4", shape, pts.data(), pts.size() * sizeof(float));
    const LightDesc light = straddlingLight();
    const nlohmann::json scene = {
        {"geometry", {{{"type", "boxes"}, {"boxes", {{{-1, 1, -1}, {0, 2, 1}}}}, {"closed", true}}}},
        {"lights", {{{"type", "rect"}, {"center", {0.004, 10, 0}}, {"u", {0.02, 0, 0}}, {"v", {0, 0, 0.5}}, {"samples", light.samples},
                     {"sample_sets", 4}}}},
        {"receivers", {{"type", "points"}, {"path", "pts.npy"}}},
        {"output", "out.npy"}};
    std::ofstream(dir / "scene.json") << scene.dump();
    auto bake = [&](const std::string& name, const std::string& args) {
        RunResult r = runPenumbra("bake " + (dir / "scene.json") + " -q " + args + " --dump " + (dir / name) + " --stats " +
                                  (dir / (name + ".json")) + " -o " + (dir / (name + ".npy")));
        INFO(r.err);
        REQUIRE(r.exitCode == 0);
        return nlohmann::json::parse(slurp(dir / (name + ".json")));
    };
    const nlohmann::json on = bake("on", "--threads 2");
    bake("on-1", "--threads 1");
    bake("ref", "--method reference");
    CHECK(on["counters"]["closed_back_faces_skipped"].get<uint64_t>() > 0);  // the bottom face is skipped...
    CHECK(on["counters"]["closed_exempt_receivers"] == 200);                // ...but not for these receivers
    RunResult cmp = runPenumbra("compare " + (dir / "on") + " " + (dir / "ref"));
    INFO(cmp.out);
    CHECK(cmp.exitCode == 0);
    CHECK_THAT(cmp.out, Catch::Contains("only_a 0\n") && Catch::Contains("only_b 0\n") && !Catch::Contains("blocked_a 0\n"));
    CHECK(slurp(dir / "on.npy") == slurp(dir / "on-1.npy"));
}

TEST_CASE("a part of a closed entry wound inward is found when its triangles are contiguous", "[closed]") {
    // One entry (one solid): a large crate wound outward, then a small one wound inward. Edges
    // balance and the total volume is positive; the second run of balanced edges is not.
    std::vector<Triangle> entry = closedBox({0, 0, 0}, {2, 2, 2});
    for (Triangle t : closedBox({5, 0, 0}, {6, 1, 1})) {
        std::swap(t.v[1], t.v[2]);
        t.flags &= ~kTriangleSolidStart;
        entry.push_back(t);
    }
    LightSamples samples;
    ClosedSolidScan scan(samples);
    scan.scan(entry);
    OpenedSolids opened = scan.finish();
    CHECK(opened.ordinals == std::vector<uint64_t>{0});
    REQUIRE(opened.leaky.size() == 1);
    CHECK(opened.leaky[0].inward == 1);
    // Both wound outward: kept.
    std::vector<Triangle> good = closedBox({0, 0, 0}, {2, 2, 2});
    for (Triangle t : closedBox({5, 0, 0}, {6, 1, 1})) t.flags = kTriangleClosed, good.push_back(t);
    ClosedSolidScan again(samples);
    again.scan(good);
    opened = again.finish();
    CHECK(opened.ordinals.empty());
    CHECK(opened.kept == 1);
}

TEST_CASE("a closed solid with faces that may let light through is opened", "[closed]") {
    std::vector<Triangle> box = closedBox({0, 0, 0}, {1, 1, 1});
    box[5].flags |= kTriangleNoCast;  // one face does not cast: a segment may leave through it
    std::vector<Triangle> opaque = closedBox({3, 0, 0}, {4, 1, 1});
    box.insert(box.end(), opaque.begin(), opaque.end());
    LightSamples samples;
    ClosedSolidScan scan(samples);
    scan.scan(box);
    const OpenedSolids opened = scan.finish();
    CHECK(opened.ordinals == std::vector<uint64_t>{0});
    CHECK(opened.kept == 1);
}
