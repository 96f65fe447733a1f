// Tests for the OBJ polygon rule (stream/PolygonTriangulation.h): convex faces keep the fan,
// concave faces are ear-clipped so that their triangles cover the face and nothing else, and the
// blocker stream and the receiver meshes agree.

#include "stream/IndexedMesh.h"
#include "stream/ObjReader.h"
#include "stream/PolygonTriangulation.h"
#include "StreamTestFiles.h"

#include <catch2/catch.hpp>

#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>

#include <cmath>
#include <random>

using namespace penumbra;
using namespace penumbra::test;

namespace {

using Tris = std::vector<std::array<uint32_t, 3>>;

Tris triangulated(const std::vector<glm::vec3>& corners) {
    Tris out;
    triangulatePolygon(corners, out);
    return out;
}

glm::dvec3 areaVector(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
    return 0.5 * glm::cross(glm::dvec3(b) - glm::dvec3(a), glm::dvec3(c) - glm::dvec3(a));
}

/// The polygon's vector area (half its Newell normal): what its triangles must sum to.
glm::dvec3 polygonArea(const std::vector<glm::vec3>& p) {
    glm::dvec3 sum(0.0);
    for (size_t i = 1; i + 1 < p.size(); ++i) sum += areaVector(p[0], p[i], p[i + 1]);
    return sum;
}

/// Every triangle wound as the polygon, and their areas adding up to the polygon's (a triangle
/// reaching outside a concave face would add area that another one must cancel with a flipped
/// winding, so both together say the triangles tile the face).
void requireTiles(const std::vector<glm::vec3>& p, const Tris& tris) {
    REQUIRE(tris.size() == p.size() - 2);
    const glm::dvec3 whole = polygonArea(p);
    const glm::dvec3 normal = glm::normalize(whole);
    double sum = 0.0;
    for (const auto& t : tris) {
        const double a = glm::dot(areaVector(p[t[0]], p[t[1]], p[t[2]]), normal);
        CHECK(a > -1e-9);
        sum += a;
    }
    CHECK(sum == Approx(glm::length(whole)).epsilon(1e-9));
}

/// An L-shaped hexagon of area 3 starting at a convex corner whose fan leaves the face.
const std::vector<glm::vec3> kL = {{2, 0, 0}, {2, 0, 1}, {1, 0, 1}, {1, 0, 2}, {0, 0, 2}, {0, 0, 0}};

}  // namespace

TEST_CASE("polygons: triangles and convex faces keep the fan", "[stream][obj]") {
    CHECK(triangulated({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}) == Tris{{0, 1, 2}});
    std::vector<glm::vec3> hexagon;
    for (int i = 0; i < 6; ++i) hexagon.emplace_back(std::cos(i * 1.0471975512), 0.0f, -std::sin(i * 1.0471975512));
    CHECK(triangulated(hexagon) == Tris{{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 5}});
    // Collinear corners (a square with its edges' midpoints) are still convex.
    CHECK(triangulated({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {2, 2, 0}, {0, 2, 0}}).front() == std::array<uint32_t, 3>{0, 1, 2});
}

TEST_CASE("polygons: a concave face is tiled, in either winding and any plane", "[stream][obj]") {
    requireTiles(kL, triangulated(kL));
    std::vector<glm::vec3> reversed(kL.rbegin(), kL.rend());
    requireTiles(reversed, triangulated(reversed));
    // Concave quads (a dart), starting at each corner: the split must use the reflex corner.
    const std::vector<glm::vec3> dart = {{0, 0, 0}, {2, 1, 0}, {0, 2, 0}, {0.5f, 1, 0}};
    for (int s = 0; s < 4; ++s) {
        std::vector<glm::vec3> d;
        for (int i = 0; i < 4; ++i) d.push_back(dart[(i + s) % 4]);
        requireTiles(d, triangulated(d));
    }
    // Random star-shaped faces (concave at every other corner), tilted into random planes.
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    for (int n : {5, 8, 17, 64}) {
        glm::vec3 axisU = glm::normalize(glm::vec3(unit(rng), unit(rng), unit(rng)));
        glm::vec3 axisV = glm::normalize(glm::cross(axisU, glm::vec3(unit(rng), unit(rng), unit(rng))));
        std::vector<glm::vec3> star;
        for (int i = 0; i < n; ++i) {
            const double angle = 6.283185307179586 * i / n, r = i % 2 ? 0.3 + 0.2 * (unit(rng) + 1) : 1.0;
            star.push_back(glm::vec3(100, -4, 7) + axisU * float(r * std::cos(angle)) + axisV * float(r * std::sin(angle)));
        }
        INFO("corners " << n);
        requireTiles(star, triangulated(star));
    }
}

TEST_CASE("polygons: faces without ears still give n - 2 triangles", "[stream][obj]") {
    CHECK(triangulated({{0, 0, 0}, {1, 1, 0}, {1, 0, 0}, {0, 1, 0}}).size() == 2);  // a bow tie
    CHECK(triangulated({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {1, 0, 0}}).size() == 3);  // a line
    CHECK(triangulated({{0, 0, 0}, {0, 0, 0}, {0, 0, 0}, {0, 0, 0}}).size() == 2);  // a point
    // A face that touches itself at a corner (two squares sharing (1, 1)).
    requireTiles({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {2, 1, 0}, {2, 2, 0}, {1, 2, 0}, {1, 1, 0}, {0, 1, 0}},
                 triangulated({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {2, 1, 0}, {2, 2, 0}, {1, 2, 0}, {1, 1, 0}, {0, 1, 0}}));
}

TEST_CASE("OBJ: a concave face casts and receives on itself only, the same in both readers", "[stream][obj]") {
    ScratchDir dir("obj-concave");
    std::string text;
    for (const glm::vec3& c : kL) text += "v " + std::to_string(c.x) + " " + std::to_string(c.y) + " " + std::to_string(c.z) + "\n";
    text += "f 1 2 3 4 5 6\n";
    writeText(dir.file("l.obj"), text);
    TriangleSourcePtr source = openObj(dir.file("l.obj"));
    const std::vector<Triangle> blockers = readAll(*source);
    REQUIRE(blockers.size() == 4);
    double area = 0.0;
    for (const Triangle& t : blockers) area += glm::length(areaVector(t.v[0], t.v[1], t.v[2]));
    CHECK(area == Approx(3.0));  // the fan from (2, 0, 0) covered 4
    const std::vector<IndexedMesh> meshes = loadIndexedMeshes(dir.file("l.obj"), glm::mat4(1.0f));
    REQUIRE(meshes.size() == 1);
    REQUIRE(meshes[0].indices.size() == 3 * blockers.size());
    for (size_t t = 0; t < blockers.size(); ++t)
        for (int k = 0; k < 3; ++k) CHECK(meshes[0].position[meshes[0].indices[3 * t + k]] == blockers[t].v[k]);
}

TEST_CASE("polygons: a concave face of a million corners ends, with n - 2 triangles", "[stream][obj]") {
    // A comb: every other corner reflex, so the ear tests cannot stop early.
    std::vector<glm::vec3> comb;
    const int teeth = 500000;
    for (int i = 0; i < teeth; ++i) comb.emplace_back(float(i), 0.0f, 0.0f), comb.emplace_back(i + 0.5f, 0.0f, 1.0f);
    comb.emplace_back(float(teeth), 0.0f, -1.0f), comb.emplace_back(0.0f, 0.0f, -1.0f);
    CHECK(triangulated(comb).size() == comb.size() - 2);
}
