// Camera receivers: a streamed z-buffer pass turns covered pixels into surface points.

#include "TestScenes.h"

#include "receivers/CameraReceivers.h"
#include "stream/util/Error.h"

#include <catch2/catch.hpp>

using namespace penumbra;
using namespace penumbra::test;

namespace {

CameraDesc frontCamera(int w = 64, int h = 48) {
    CameraDesc c;
    c.eye = {0, 0, 5}, c.target = {0, 0, 0}, c.up = {0, 1, 0}, c.fovDeg = 60, c.width = w, c.height = h;
    return c;
}

}  // namespace

TEST_CASE("a quad facing the camera becomes receivers on its surface", "[receivers][camera]") {
    std::vector<Triangle> tris;
    addQuad(tris, {-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0});
    VectorSource source(tris);
    CameraDesc cam = frontCamera();
    ReceiverSet r = rasterizeCamera(source, cam);
    // The quad spans 2 units at distance 5 with a 60 degree vertical fov: 2 / (2 * 5 * tan 30) of
    // the height, i.e. about 16.6 of 48 rows and as many columns.
    REQUIRE(r.size() > 14 * 14);
    REQUIRE(r.size() < 19 * 19);
    for (size_t i = 0; i < r.size(); ++i) {
        CHECK(std::abs(r.position[i].z) < 1e-5f);
        CHECK(std::abs(r.position[i].x) <= 1.0f);
        CHECK(r.normal[i].z == Approx(1.0f));
        int x = int(r.pixel[i] % 64), y = int(r.pixel[i] / 64);
        glm::dvec3 d = cam.pixelDirection(x, y);
        CHECK(glm::length(glm::dvec3(r.position[i]) - (cam.eye + double(r.depth[i]) * d)) < 1e-5);
    }
}

TEST_CASE("the nearest surface wins and back faces are turned to the camera", "[receivers][camera]") {
    std::vector<Triangle> tris;
    addQuad(tris, {-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0});
    addQuad(tris, {-0.5f, -0.5f, 1}, {-0.5f, 0.5f, 1}, {0.5f, 0.5f, 1}, {0.5f, -0.5f, 1});  // nearer, wound backwards
    VectorSource source(tris);
    ReceiverSet r = rasterizeCamera(source, frontCamera());
    int near = 0;
    for (size_t i = 0; i < r.size(); ++i) {
        if (std::abs(r.position[i].z - 1.0f) < 1e-5f) {
            ++near;
            CHECK(r.normal[i].z == Approx(1.0f));
        }
        if (std::abs(r.position[i].x) < 0.3f && std::abs(r.position[i].y) < 0.3f) CHECK(r.position[i].z > 0.99f);
    }
    CHECK(near > 20);
}

TEST_CASE("triangles behind or through the eye are clipped, not mirrored", "[receivers][camera]") {
    std::vector<Triangle> tris;
    addQuad(tris, {-1, -1, 10}, {1, -1, 10}, {1, 1, 10}, {-1, 1, 10});  // behind the camera
    tris.push_back({{glm::vec3(-50, -1, -50), glm::vec3(50, -1, -50), glm::vec3(0, -1, 50)}, 0});  // floor through the eye plane
    VectorSource source(tris);
    ReceiverSet r = rasterizeCamera(source, frontCamera());
    REQUIRE(r.size() > 0);
    for (size_t i = 0; i < r.size(); ++i) {
        CHECK(r.position[i].y == Approx(-1.0f).margin(1e-4));
        CHECK(r.position[i].z < 5.0f);
    }
}

TEST_CASE("bad cameras are rejected with the field named", "[receivers][camera]") {
    CameraDesc c = frontCamera();
    c.where = "scene.json: receivers";
    c.fovDeg = 0;
    CHECK_THROWS_WITH(validateCamera(c), Catch::Contains("fov_deg"));
    c = frontCamera();
    c.target = c.eye;
    CHECK_THROWS_AS(validateCamera(c), InputError);
    c = frontCamera();
    c.up = {0, 0, 1};
    CHECK_THROWS_WITH(validateCamera(c), Catch::Contains("up"));
}
