// Closed solids whose faces cross one another (SolidSelfIntersection.h) are cast as open
// surfaces: a watertight box pushed through itself has a wedge of negative winding number, where
// closed casters lost the shadow of the face they skipped (stop-58 sweep). Valid solids, rotated
// and rounded to float, must stay closed, or GRIDS loses its closed casters.

#include "CliRunner.h"
#include "TestSupport.h"

#include "bake/cast/ClosedSolids.h"
#include "bake/cast/SolidSelfIntersection.h"
#include "procedural/BoxFaces.h"
#include "stream/util/Npy.h"

#include <catch2/catch.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <random>

using namespace penumbra;
using namespace penumbra::test;

namespace {

std::vector<SolidTriangle> box(const glm::mat4& m) {
    auto corner = [&](int c) { return glm::vec3(m * glm::vec4(c & 1 ? 1 : 0, c & 2 ? 1 : 0, c & 4 ? 1 : 0, 1)); };
    std::vector<SolidTriangle> out;
    for (const auto& f : kBoxFaceTriangles) out.push_back({{corner(f[0]), corner(f[1]), corner(f[2])}});
    return out;
}

/// A sphere of 8 * 4^level triangles (an octahedron subdivided and pushed out), wound outward.
std::vector<SolidTriangle> sphere(int level, const glm::mat4& m) {
    std::vector<SolidTriangle> t;
    const glm::vec3 x(1, 0, 0), y(0, 1, 0), z(0, 0, 1);
    for (int sx : {-1, 1})
        for (int sy : {-1, 1})
            for (int sz : {-1, 1}) {
                SolidTriangle f{{float(sx) * x, float(sy) * y, float(sz) * z}};
                if (sx * sy * sz < 0) std::swap(f.v[1], f.v[2]);
                t.push_back(f);
            }
    for (int l = 0; l < level; ++l) {
        std::vector<SolidTriangle> next;
        for (const SolidTriangle& f : t) {
            const glm::vec3 a = glm::normalize(f.v[0] + f.v[1]), b = glm::normalize(f.v[1] + f.v[2]), c = glm::normalize(f.v[2] + f.v[0]);
            next.push_back({{f.v[0], a, c}}), next.push_back({{a, f.v[1], b}}), next.push_back({{c, b, f.v[2]}}), next.push_back({{a, b, c}});
        }
        t.swap(next);
    }
    for (SolidTriangle& f : t)
        for (glm::vec3& v : f.v) v = glm::vec3(m * glm::vec4(v, 1));
    return t;
}

glm::mat4 randomPlacement(std::mt19937& rng) {
    std::uniform_real_distribution<float> u(-1, 1);
    glm::mat4 m = glm::translate(glm::mat4(1), glm::vec3(u(rng), u(rng), u(rng)) * 1000.0f);
    m = glm::rotate(m, 3.14159f * u(rng), glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0.01f)));
    return glm::scale(m, glm::vec3(0.1f + std::abs(u(rng)), 0.01f + std::abs(u(rng)), 0.5f + std::abs(u(rng))));
}

}  // namespace

TEST_CASE("valid closed solids, rotated and rounded to float, do not cross themselves", "[closed][crossing]") {
    std::mt19937 rng(58);
    for (int i = 0; i < 300; ++i) {
        const glm::mat4 m = randomPlacement(rng);
        std::vector<SolidTriangle> b = box(m);
        INFO("placement " << i);
        CHECK_FALSE(solidMayCrossItself(b));
        if (i % 30 == 0) {
            std::vector<SolidTriangle> s = sphere(3, m);  // 512 triangles, thin and flat ones too
            CHECK_FALSE(solidMayCrossItself(s));
        }
    }
    std::vector<SolidTriangle> unit = box(glm::mat4(1));
    CHECK_FALSE(solidMayCrossItself(unit));
}

TEST_CASE("faces pushed through one another are crossings, shared corners or not", "[closed][crossing]") {
    // No shared corner: one triangle pierces the other.
    const SolidTriangle flat{{{0, 0, 0}, {2, 0, 0}, {0, 2, 0}}};
    CHECK(trianglesMayCross(flat, {{{0.5f, 0.5f, -1}, {0.5f, 0.5f, 1}, {3, 3, 0.5f}}}));
    CHECK_FALSE(trianglesMayCross(flat, {{{0.5f, 0.5f, 0.25f}, {0.5f, 0.6f, 1}, {3, 3, 0.5f}}}));  // above it
    // Coplanar: overlapping, and apart.
    CHECK(trianglesMayCross(flat, {{{0.2f, 0.2f, 0}, {3, 0.2f, 0}, {0.2f, 3, 0}}}));
    CHECK_FALSE(trianglesMayCross(flat, {{{2, 2, 0}, {4, 2, 0}, {2, 4, 0}}}));
    // One shared corner: a fan of one face (apart), and a fold (as in cow.obj: the two planes'
    // line leaves the corner into both triangles).
    CHECK_FALSE(trianglesMayCross(flat, {{{0, 0, 0}, {-1, 0, 0}, {0, -1, 0}}}));
    CHECK_FALSE(trianglesMayCross(flat, {{{0, 0, 0}, {0, 2, 1}, {2, 0, 1}}}));  // a box corner's neighbour
    CHECK(trianglesMayCross(flat, {{{0, 0, 0}, {1, 0.2f, 0.5f}, {1, 0.4f, -0.5f}}}));
    CHECK(trianglesMayCross(flat, {{{0, 0, 0}, {1, 1, 0}, {2, 1, 0}}}));  // folded flat onto it
    // A shared edge: a crease (apart) and a fin folded back onto the face.
    CHECK_FALSE(trianglesMayCross(flat, {{{2, 0, 0}, {0, 0, 0}, {1, -1, 0}}}));
    CHECK_FALSE(trianglesMayCross(flat, {{{2, 0, 0}, {0, 0, 0}, {1, 0.5f, 1}}}));
    CHECK(trianglesMayCross(flat, {{{2, 0, 0}, {0, 0, 0}, {1, 0.5f, 0}}}));
    CHECK(trianglesMayCross(flat, {{{2, 0, 0}, {0, 2, 0}, {0, 0, 0}}}));  // the same face twice
}

TEST_CASE("random piercing pairs are always found", "[closed][crossing]") {
    // B's first edge passes through a point well inside A: whatever else B does, they cross.
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-1, 1), w(0.1f, 0.8f);
    for (int i = 0; i < 2000; ++i) {
        const SolidTriangle a{{{u(rng), u(rng), u(rng)}, {u(rng), u(rng), u(rng)}, {u(rng), u(rng), u(rng)}}};
        const glm::vec3 n = glm::cross(a.v[1] - a.v[0], a.v[2] - a.v[0]);
        if (glm::length(n) < 0.05f) continue;
        float s = w(rng), t = w(rng) * (1 - s);
        const glm::vec3 p = a.v[0] + s * (a.v[1] - a.v[0]) + t * (a.v[2] - a.v[0]);
        const glm::vec3 d = glm::normalize(n) * (0.2f + std::abs(u(rng)));
        const glm::vec3 tilt(u(rng) * 0.3f, u(rng) * 0.3f, u(rng) * 0.3f);
        const SolidTriangle b{{p - d + tilt, p + d - tilt, glm::vec3(u(rng), u(rng), u(rng)) * 3.0f}};
        INFO("pair " << i);
        CHECK(trianglesMayCross(a, b));
        CHECK(trianglesMayCross(b, a));
    }
}

TEST_CASE("the scan opens a solid that crosses itself and one too large to check", "[closed][crossing]") {
    LightSamples samples;
    // The stop-58 wedge: a box whose top face slopes down through the plane of its bottom face.
    std::vector<Triangle> wedge;
    const float c[8][3] = {{-1, 1, -0.5f}, {1, 1, -0.5f}, {1, 1, 0.5f}, {-1, 1, 0.5f},
                           {-1, 3, -0.5f}, {1, 0.5f, -0.5f}, {1, 0.5f, 0.5f}, {-1, 3, 0.5f}};
    const int faces[12][3] = {{0, 1, 2}, {0, 2, 3}, {4, 7, 6}, {4, 6, 5}, {0, 4, 5}, {0, 5, 1},
                              {3, 2, 6}, {3, 6, 7}, {0, 3, 7}, {0, 7, 4}, {1, 5, 6}, {1, 6, 2}};
    for (const auto& f : faces) {
        Triangle t{};
        for (int k = 0; k < 3; ++k) t.v[k] = {c[f[k]][0], c[f[k]][1], c[f[k]][2]};
        t.flags = kTriangleClosed;
        wedge.push_back(t);
    }
    auto scanned = [&samples](const std::vector<Triangle>& stream) {
        ClosedSolidScan scan(samples);
        scan.scan(stream);
        return scan.finish();
    };
    OpenedSolids opened = scanned(wedge);
    CHECK(opened.ordinals == std::vector<uint64_t>{0});
    REQUIRE(opened.leaky.size() == 1);
    CHECK(opened.leaky[0].crossing == 1);
    CHECK(opened.leakySolids() == 0);  // watertight and outward: only the crossing opened it

    // A sphere of 131,072 triangles, valid but more than the scan holds.
    std::vector<Triangle> big;
    for (const SolidTriangle& s : sphere(7, glm::mat4(1))) big.push_back({{s.v[0], s.v[1], s.v[2]}, kTriangleClosed});
    REQUIRE(big.size() > kMaxCheckedSolidTriangles);
    opened = scanned(big);
    REQUIRE(opened.leaky.size() == 1);
    CHECK(opened.leaky[0].unchecked == 1);
    CHECK(opened.uncheckedSolids() == 1);
}

TEST_CASE("a closed OBJ pushed through itself keeps every shadow, and the bake names it", "[closed][crossing][exact]") {
    ScratchDir dir("crossing");
    std::ofstream obj(dir / "wedge.obj");
    obj << "v -1 1 -0.5\nv 1 1 -0.5\nv 1 1 0.5\nv -1 1 0.5\nv -1 3 -0.5\nv 1 0.5 -0.5\nv 1 0.5 0.5\nv -1 3 0.5\n"
           "f 1 2 3\nf 1 3 4\nf 5 8 7\nf 5 7 6\nf 1 5 6\nf 1 6 2\nf 4 3 7\nf 4 7 8\nf 1 4 8\nf 1 8 5\nf 2 6 7\nf 2 7 3\n";
    obj.close();
    const std::vector<float> pts = {0.8f, 0.9f, 0, 0, 1, 0, 0.7f, 0.95f, -0.2f, 0, 1, 0, 0.9f, 0.85f, 0.3f, 0, 1, 0, -0.5f, 0.5f, 0, 0, 1, 0};
    const uint64_t shape[2] = {4, 6};
    writeNpy(dir / "pts.npy", "<f4", shape, pts.data(), pts.size() * sizeof(float));
    const nlohmann::json scene = {{"geometry", {{{"type", "obj"}, {"path", "wedge.obj"}, {"closed", true}}}},
                                  {"lights", {{{"type", "rect"}, {"center", {0.2, 4.5, 0.1}}, {"u", {1.5, 0, 0}}, {"v", {0, 0, 1.5}}, {"samples", 64}}}},
                                  {"receivers", {{"type", "points"}, {"path", "pts.npy"}}}, {"output", "v.npy"}};
    std::ofstream(dir / "scene.json") << scene.dump();
    RunResult hpc = runPenumbra("bake " + dir / "scene.json" + " --threads 2 --dump " + dir / "hpc" + " --stats " + dir / "s.json");
    INFO(hpc.err);
    REQUIRE(hpc.exitCode == 0);
    CHECK_THAT(hpc.err, Catch::Contains("wedge.obj) is marked closed, but 1 of its solids has faces that cross one another"));
    const nlohmann::json stats = nlohmann::json::parse(slurp(dir / "s.json"));
    CHECK(stats["counters"]["closed_solids_crossing"] == 1);
    RunResult ref = runPenumbra("bake " + dir / "scene.json" + " -q --method reference --dump " + dir / "ref" + " -o " + dir / "ref.npy");
    REQUIRE(ref.exitCode == 0);
    RunResult cmp = runPenumbra("compare " + dir / "hpc" + " " + dir / "ref");
    INFO(cmp.out);
    CHECK(cmp.exitCode == 0);
    CHECK_THAT(cmp.out, Catch::Contains("only_a 0\n") && Catch::Contains("only_b 0\n") && !Catch::Contains("blocked_a 0\n"));
}

TEST_CASE("a part wound inward is found even when its triangles interleave with another part's", "[closed][crossing]") {
    // Two crates in one solid, the small one wound inward, their triangles alternating in the
    // stream (split by material over shared primitives): the running check saw one surface of
    // positive volume, and receivers inside the small crate lost its shadows (stop-55 sweep).
    std::vector<SolidTriangle> outer = box(glm::scale(glm::mat4(1), glm::vec3(2))), inner = box(glm::translate(glm::mat4(1), glm::vec3(5, 0, 0)));
    std::vector<Triangle> stream;
    for (size_t i = 0; i < outer.size(); ++i) {
        stream.push_back({{outer[i].v[0], outer[i].v[1], outer[i].v[2]}, kTriangleClosed});
        stream.push_back({{inner[i].v[0], inner[i].v[2], inner[i].v[1]}, kTriangleClosed});  // wound inward
    }
    CHECK(solidParts(std::vector<SolidTriangle>(inner.size(), SolidTriangle{})).inward);  // flat parts count too
    LightSamples samples;
    ClosedSolidScan scan(samples);
    scan.scan(stream);
    const OpenedSolids opened = scan.finish();
    CHECK(opened.ordinals == std::vector<uint64_t>{0});
    REQUIRE(opened.leaky.size() == 1);
    CHECK(opened.leaky[0].inward == 1);
    // Both wound outward, interleaved the same way: kept.
    std::vector<SolidTriangle> both;
    for (size_t i = 0; i < outer.size(); ++i) both.push_back(outer[i]), both.push_back(inner[i]);
    CHECK_FALSE(solidParts(both).inward);
    CHECK_FALSE(solidParts(both).sharedEdge);
    CHECK_FALSE(solidMayCrossItself(both));
}

TEST_CASE("sheets that cross along edges both share are a crossing", "[closed][crossing]") {
    // An extruded figure eight: its two lobes meet at the edge (2,0,1)-(2,1,1), which four faces
    // use; no pair of faces crosses, and one lobe is wound inward (stop-58 sweep: receivers in
    // it lost every shadow).
    const glm::vec3 c[10] = {{0, 0, 0}, {0, 0, 2}, {0, 1, 0}, {0, 1, 2}, {2, 0, 1}, {2, 1, 1}, {3, 0, 0}, {3, 0, 2}, {3, 1, 0}, {3, 1, 2}};
    const int f[16][3] = {{1, 6, 5}, {1, 3, 6}, {5, 10, 8}, {5, 6, 10}, {8, 9, 7}, {8, 10, 9}, {7, 6, 5}, {7, 9, 6},
                          {5, 4, 2}, {5, 6, 4}, {2, 3, 1}, {2, 4, 3}, {3, 4, 6}, {1, 5, 2}, {6, 9, 10}, {5, 8, 7}};
    std::vector<SolidTriangle> bowtie;
    for (const auto& t : f) bowtie.push_back({{c[t[0] - 1], c[t[1] - 1], c[t[2] - 1]}});
    CHECK(solidParts(bowtie).sharedEdge);
    std::vector<Triangle> stream;
    for (const SolidTriangle& s : bowtie) stream.push_back({{s.v[0], s.v[1], s.v[2]}, kTriangleClosed});
    LightSamples samples;
    ClosedSolidScan scan(samples);
    scan.scan(stream);
    const OpenedSolids opened = scan.finish();
    CHECK(opened.ordinals == std::vector<uint64_t>{0});
    CHECK(opened.crossingSolids() + opened.leakySolids() == 1);
    std::vector<SolidTriangle> plain = box(glm::mat4(1));
    CHECK_FALSE(solidParts(plain).sharedEdge);
}
