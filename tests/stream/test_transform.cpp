// Tests for Transform (scale, Euler rotation order, translation) and TransformedSource.

#include "stream/util/Error.h"
#include "stream/Transform.h"
#include "StreamTestFiles.h"

#include <catch2/catch.hpp>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/matrix.hpp>

#include <cmath>
#include <limits>

using namespace penumbra;
using penumbra::test::tri;

namespace {

glm::vec3 apply(const glm::mat4& m, glm::vec3 p) { return glm::vec3(m * glm::vec4(p, 1.0f)); }

bool near(glm::vec3 a, glm::vec3 b, float eps = 1e-5f) { return glm::all(glm::lessThanEqual(glm::abs(a - b), glm::vec3(eps))); }

glm::vec3 normalOf(const Triangle& t) { return glm::normalize(glm::cross(t.v[1] - t.v[0], t.v[2] - t.v[0])); }

}  // namespace

TEST_CASE("Transform: default is the identity", "[stream][transform]") {
    Transform t;
    CHECK(t.matrix() == glm::mat4(1.0f));
    CHECK(t.isIdentity());
    t.rotateDeg = {360, -720, 0};
    CHECK(t.isIdentity());
    t.translate.x = 1;
    CHECK_FALSE(t.isIdentity());
}

TEST_CASE("Transform: scale first, translate last", "[stream][transform]") {
    Transform t;
    t.scale = 2;
    t.translate = {10, 0, -1};
    CHECK(apply(t.matrix(), {1, 2, 3}) == glm::vec3(12, 4, 5));
}

TEST_CASE("Transform: rotates about X, then Y, then Z", "[stream][transform]") {
    Transform t;
    t.rotateDeg = {90, 90, 0};
    // X first takes +Y to +Z, then Y takes +Z to +X. The other order would leave +Y at +Z.
    CHECK(apply(t.matrix(), {0, 1, 0}) == glm::vec3(1, 0, 0));

    t.rotateDeg = {0, 90, 90};
    // Y first takes +Z to +X, then Z takes +X to +Y.
    CHECK(apply(t.matrix(), {0, 0, 1}) == glm::vec3(0, 1, 0));

    Transform z;
    z.rotateDeg.z = 90;
    CHECK(apply(z.matrix(), {1, 0, 0}) == glm::vec3(0, 1, 0));  // right-handed, counter-clockwise
}

TEST_CASE("Transform: quarter turns are exact", "[stream][transform]") {
    for (float degrees : {90.0f, 180.0f, 270.0f, -90.0f, 450.0f, -270.0f}) {
        Transform t;
        t.rotateDeg = {degrees, degrees, degrees};
        glm::mat4 m = t.matrix();
        for (int c = 0; c < 3; ++c)
            for (int r = 0; r < 3; ++r) {
                INFO("degrees " << degrees << " m[" << c << "][" << r << "] = " << m[c][r]);
                CHECK((m[c][r] == 0.0f || m[c][r] == 1.0f || m[c][r] == -1.0f));
            }
    }
}

TEST_CASE("Transform: matches T * Rz * Ry * Rx * S for arbitrary angles", "[stream][transform]") {
    Transform t;
    t.scale = 0.5f;
    t.rotateDeg = {17, -33, 251};
    t.translate = {1, -2, 3};
    glm::mat4 expected = glm::translate(glm::mat4(1), t.translate) *
                         glm::rotate(glm::mat4(1), glm::radians(251.0f), glm::vec3(0, 0, 1)) *
                         glm::rotate(glm::mat4(1), glm::radians(-33.0f), glm::vec3(0, 1, 0)) *
                         glm::rotate(glm::mat4(1), glm::radians(17.0f), glm::vec3(1, 0, 0)) *
                         glm::scale(glm::mat4(1), glm::vec3(0.5f));
    glm::mat4 m = t.matrix();
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) CHECK(m[c][r] == Approx(expected[c][r]).margin(1e-6));
}

TEST_CASE("TransformedSource: transforms every vertex and forwards the rest", "[stream][transform]") {
    std::vector<Triangle> in;
    for (int i = 0; i < 10; ++i) in.push_back(tri({i, 0, 0}, {i, 1, 0}, {i, 0, 1}, uint32_t(i)));
    Transform t;
    t.scale = 3;
    t.translate = {0, 0, 5};
    TransformedSource source(std::make_unique<VectorSource>(in, "things"), t.matrix());
    CHECK(source.name() == "things");
    CHECK(source.sizeHint() == 10u);

    std::vector<Triangle> out = readAll(source);
    REQUIRE(out.size() == 10);
    for (size_t i = 0; i < out.size(); ++i) {
        CHECK(out[i].flags == i);
        for (int k = 0; k < 3; ++k) CHECK(out[i].v[k] == in[i].v[k] * 3.0f + glm::vec3(0, 0, 5));
    }
    source.rewind();
    CHECK(readAll(source).size() == 10);
}

TEST_CASE("TransformedSource: a mirroring matrix keeps triangles facing outward", "[stream][transform]") {
    Triangle t = tri({0, 0, 0}, {1, 0, 0}, {0, 1, 0});  // normal +Z
    glm::mat4 rotate = Transform{1, {20, 40, 60}, {0, 0, 0}}.matrix();
    for (glm::vec3 mirror : {glm::vec3(-1, 1, 1), glm::vec3(1, 1, -1), glm::vec3(-1, -1, -1), glm::vec3(1, 1, 1)}) {
        glm::mat4 m = rotate * glm::scale(glm::mat4(1), mirror);
        TransformedSource source(std::make_unique<VectorSource>(std::vector{t}), m);
        std::vector<Triangle> out = readAll(source);
        REQUIRE(out.size() == 1);
        // Normals transform with the inverse transpose; the emitted winding must agree.
        glm::vec3 expected = glm::normalize(glm::transpose(glm::inverse(glm::mat3(m))) * normalOf(t));
        INFO("mirror " << mirror.x << " " << mirror.y << " " << mirror.z);
        CHECK(near(normalOf(out[0]), expected));
    }
}

TEST_CASE("TransformedSource: non-finite results are input errors", "[stream][transform]") {
    glm::mat4 m(1.0f);
    m[0][0] = std::numeric_limits<float>::infinity();
    TransformedSource source(std::make_unique<VectorSource>(std::vector{tri({1, 0, 0}, {0, 1, 0}, {0, 0, 1})}, "inf"), m);
    CHECK_THROWS_AS(readAll(source), InputError);
}
