// "boxes" and "colonnade": 12 outward-facing triangles per box, the colonnade's layout as
// documented, determinism, and clean errors for bad parameters.

#include "ProceduralTestUtil.h"

#include "procedural/BoxesGenerator.h"

using namespace penumbra;
using namespace penumbra::test;

TEST_CASE("boxes: 12 outward-facing triangles per box", "[procedural]") {
    nlohmann::json e = {{"type", "boxes"}, {"boxes", {{{0, 0, 0}, {1, 2, 3}}, {{-5, 1, -5}, {-4, 1.5, 5}}}}};
    requireDeterministic(e);
    TriangleSourcePtr source = openEntry(e);
    REQUIRE(source->sizeHint() == 24u);
    StreamSummary s = summarise(*source, true);
    CHECK(s.degenerate == 0);
    CHECK(s.lo == glm::dvec3(-5, 0, -5));
    CHECK(s.hi == glm::dvec3(1, 2, 5));
    // Outward: each normal points away from its box's centre, and each box's area is right.
    const glm::dvec3 centres[2] = {{0.5, 1, 1.5}, {-4.5, 1.25, 0}};
    double area[2] = {0, 0};
    for (size_t i = 0; i < 24; ++i) {
        const Triangle& t = s.triangles[i];
        const glm::dvec3 a(t.v[0]), b(t.v[1]), c(t.v[2]);
        const glm::dvec3 n = glm::cross(b - a, c - a);
        CHECK(glm::dot(n, (a + b + c) / 3.0 - centres[i / 12]) > 0);
        // Each box is one closed solid: its first triangle starts it.
        CHECK(t.flags == (kTriangleClosed | (i % 12 == 0 ? kTriangleSolidStart : 0u)));
        area[i / 12] += 0.5 * glm::length(n);
    }
    CHECK(area[0] == Approx(2 * (1 * 2 + 2 * 3 + 1 * 3)));
    CHECK(area[1] == Approx(2 * (1 * 0.5 + 0.5 * 10 + 1 * 10)));
}

TEST_CASE("colonnade: columns, gallery slabs, wall and floor as documented", "[procedural]") {
    nlohmann::json e = {{"type", "colonnade"}, {"courtyard", {12, 8}}, {"columns", {7, 5}}, {"storeys", 2},
                        {"gallery", 2}, {"wall", 0.4}, {"storey_height", 3}, {"center", {1, 0, -1}}};
    requireDeterministic(e);
    nlohmann::json params = e;
    params.erase("type");
    ColonnadeParams p = parseColonnadeParams(SourceRequest{params, "scene.json", "geometry[0]", "."});
    std::vector<BoxShape> boxes = colonnadeBoxes(p);
    // Per storey 2 x 7 + 2 x 3 columns and 4 slabs; 4 walls; 1 floor.
    CHECK(boxes.size() == 2u * (14 + 6 + 4) + 4 + 1);
    TriangleSourcePtr source = openEntry(e);
    CHECK(source->sizeHint() == boxes.size() * 12);
    StreamSummary s = summarise(*source);
    CHECK(s.degenerate == 0);
    CHECK(s.nonFinite == 0);
    CHECK(s.lo.x == Approx(1 - 6 - 2 - 0.4));
    CHECK(s.hi.x == Approx(1 + 6 + 2 + 0.4));
    CHECK(s.lo.z == Approx(-1 - 4 - 2 - 0.4));
    CHECK(s.lo.y == Approx(-0.1));
    CHECK(s.hi.y == Approx(6));
    // The courtyard itself stays open to the sky: no box covers its middle above the floor.
    for (const BoxShape& b : boxes)
        if (b.hi.y > 0) CHECK_FALSE((b.lo.x < 1 && b.hi.x > 1 && b.lo.z < -1 && b.hi.z > -1));
    CHECK(openEntry({{"type", "colonnade"}, {"wall", 0}, {"floor", false}, {"storeys", 1}})->sizeHint() ==
          12u * (2 * 9 + 2 * 4 + 4));
}

TEST_CASE("boxes and colonnade: bad parameters give an error naming the key", "[procedural]") {
    requireInputError({{"type", "boxes"}}, "scene.json: geometry[0].boxes: missing required field");
    requireInputError({{"type", "boxes"}, {"boxes", 3}}, "geometry[0].boxes: expected an array");
    requireInputError({{"type", "boxes"}, {"boxes", {{{0, 0, 0}, {1, 0, 1}}}}}, "geometry[0].boxes[0]: box is empty");
    requireInputError({{"type", "boxes"}, {"boxes", {{{0, 0, 0}, {1, 1, 1}}, {1, 2}}}}, "geometry[0].boxes[1]");
    requireInputError({{"type", "boxes"}, {"boxes", {{{0, 0, 0}, {1, 1, "x"}}}}}, "geometry[0].boxes[0].hi");
    requireInputError({{"type", "colonnade"}, {"columns", {1, 5}}}, "geometry[0].columns");
    requireInputError({{"type", "colonnade"}, {"courtyard", {0, 5}}}, "geometry[0].courtyard");
    requireInputError({{"type", "colonnade"}, {"column_width", 5}}, "geometry[0].column_width");
    requireInputError({{"type", "colonnade"}, {"slab", 5}}, "geometry[0].slab");
    requireInputError({{"type", "colonnade"}, {"storeys", -1}}, "geometry[0].storeys: must be in 1..100");
    requireInputError({{"type", "colonnade"}, {"roof", true}}, "geometry[0].roof: unknown key");
}
