// Camera receivers: a streamed z-buffer pass turns covered pixels into surface points.

#include "TestScenes.h"

#include "receivers/CameraReceivers.h"
#include "stream/util/Error.h"

#include <catch2/catch.hpp>
#include <glm/geometric.hpp>
#include <tbb/global_control.h>

#include <algorithm>
#include <random>

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

TEST_CASE("a wide floor through the eye's plane is drawn however far off screen its clipped corners land", "[receivers][camera]") {
    // Clipped at the near plane (1e-6 in front of the eye), the floor's corners 579 units to
    // either side project to about 2.4e10 pixels. Before the pixel bounds were clamped ahead of
    // their conversion to int, the right corner's bound became INT_MIN and the floor vanished.
    std::vector<Triangle> tris;
    tris.push_back({{glm::vec3(-600, -1, 7), glm::vec3(600, -1, 7), glm::vec3(0, -1, -50)}, 0});
    VectorSource source(tris);
    const ReceiverSet r = rasterizeCamera(source, frontCamera());
    // Seen from one unit above it, the floor fills the rows below the horizon (row 24.75 of 48)
    // out to its far corner: 23 rows of 64, less the corners beside the far vertex.
    CHECK(r.size() > 20 * 64);
    for (size_t i = 0; i < r.size(); ++i) CHECK(r.position[i].y == Approx(-1.0f).margin(1e-4));
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

// The rasterizer tests only the pixels near each row's span of the polygon. Against an
// independent ray-triangle test per pixel centre, over the whole image: every pixel clearly
// inside a triangle is covered, none clearly outside is (pixels within 1e-7 of an edge in
// barycentric terms may go either way). Slivers, large triangles, triangles through the eye's
// plane and far beyond the image edges are included.
TEST_CASE("each triangle covers exactly the pixels whose rays hit it", "[receivers][camera]") {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> coord(-6.0f, 6.0f), depth(-4.0f, 4.5f), sliver(-0.002f, 0.002f);
    const CameraDesc cam = frontCamera(96, 64);
    for (int trial = 0; trial < 60; ++trial) {
        glm::vec3 a(coord(rng), coord(rng), depth(rng)), b(coord(rng), coord(rng), depth(rng)), c(coord(rng), coord(rng), depth(rng));
        if (trial % 4 == 1) c = a + (b - a) * 0.37f + glm::vec3(sliver(rng), sliver(rng), 0.0f);  // a sliver
        if (trial % 4 == 2) a *= 400.0f;  // one vertex far outside the view
        std::vector<Triangle> tris{{{a, b, c}, 0}};
        VectorSource source(tris);
        const ReceiverSet r = rasterizeCamera(source, cam);
        std::vector<char> covered(size_t(cam.width) * cam.height, 0);
        for (uint32_t p : r.pixel) covered[p] = 1;
        const glm::dvec3 A(a), B(b), C(c);
        int inside = 0;
        for (int y = 0; y < cam.height; ++y)
            for (int x = 0; x < cam.width; ++x) {
                // Möller–Trumbore from the eye along the pixel's ray.
                const glm::dvec3 d = cam.pixelDirection(x, y), e1 = B - A, e2 = C - A, s = cam.eye - A;
                const glm::dvec3 pv = glm::cross(d, e2), qv = glm::cross(s, e1);
                const double det = glm::dot(e1, pv);
                if (std::abs(det) < 1e-12) continue;
                const double u = glm::dot(s, pv) / det, v = glm::dot(d, qv) / det, t = glm::dot(e2, qv) / det;
                const double w = 1 - u - v, margin = 1e-7;
                const bool clearlyIn = u > margin && v > margin && w > margin && t > 1e-4;
                const bool clearlyOut = u < -margin || v < -margin || w < -margin || t < -1e-4;
                const char got = covered[size_t(y) * cam.width + x];
                if (clearlyIn) {
                    ++inside;
                    CHECK(got == 1);
                }
                if (clearlyOut) CHECK(got == 0);
            }
        CHECK(int(std::count(covered.begin(), covered.end(), 1)) >= inside);
    }
}

TEST_CASE("in a deep stack of triangles each pixel keeps the nearest surfaces a ray cast finds", "[receivers][camera]") {
    // Most depth tests lose to a nearer surface (the scan skips their division); none of the
    // surfaces a ray finds nearest may be lost, in any slot of a deep pixel.
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> coord(-5.0f, 5.0f), depth(-3.0f, 3.0f);
    CameraDesc cam = frontCamera(80, 60);
    cam.layers = GENERATE(1, 3);
    std::vector<Triangle> tris;
    for (int i = 0; i < 60; ++i)
        tris.push_back({{glm::vec3(coord(rng), coord(rng), depth(rng)), glm::vec3(coord(rng), coord(rng), depth(rng)),
                         glm::vec3(coord(rng), coord(rng), depth(rng))},
                        0});
    VectorSource source(tris);
    const ReceiverSet r = rasterizeCamera(source, cam);
    const size_t pixels = size_t(cam.width) * cam.height;
    std::vector<std::vector<float>> kept(pixels);
    for (size_t i = 0; i < r.size(); ++i) kept[r.pixel[i] % pixels].push_back(r.depth[i]);
    int checked = 0;
    for (int y = 0; y < cam.height; ++y)
        for (int x = 0; x < cam.width; ++x) {
            // Möller–Trumbore against every triangle; a pixel counts only when every hit is
            // clearly inside or outside, and its hits are clearly apart.
            const glm::dvec3 d = cam.pixelDirection(x, y);
            std::vector<double> hits;
            bool clear = true;
            for (const Triangle& t : tris) {
                const glm::dvec3 A(t.v[0]), e1 = glm::dvec3(t.v[1]) - A, e2 = glm::dvec3(t.v[2]) - A, s = cam.eye - A;
                const glm::dvec3 pv = glm::cross(d, e2), qv = glm::cross(s, e1);
                const double det = glm::dot(e1, pv);
                if (std::abs(det) < 1e-9) continue;
                const double u = glm::dot(s, pv) / det, v = glm::dot(d, qv) / det, w = 1 - u - v, along = glm::dot(e2, qv) / det;
                const double margin = 1e-6;
                if (u > margin && v > margin && w > margin && along > 1e-3) hits.push_back(along);
                else if (!(u < -margin || v < -margin || w < -margin || along < -1e-3)) clear = false;
            }
            std::sort(hits.begin(), hits.end());
            for (size_t k = 1; k < hits.size(); ++k) clear = clear && hits[k] - hits[k - 1] > 1e-4;
            if (!clear) continue;
            ++checked;
            const std::vector<float>& got = kept[size_t(y) * cam.width + x];
            const size_t want = std::min(hits.size(), size_t(cam.layers));
            REQUIRE(got.size() == want);
            for (size_t k = 0; k < want; ++k) CHECK(std::abs(double(got[k]) - hits[k]) <= 1e-5 * hits[k]);
        }
    CHECK(checked > int(pixels) / 2);
}

namespace {

/// Everything a rasterizer hands on, from @p chunks of random triangles, with TBB limited to
/// @p threads (one thread draws each triangle whole; more draw bands of rows in parallel).
struct RasterResult {
    ReceiverSet set;
    std::vector<uint64_t> ids;
    std::vector<uint8_t> classes;
};
RasterResult rasterizeWithThreads(const std::vector<std::vector<Triangle>>& chunks, const CameraDesc& cam, int threads,
                                  std::span<const uint32_t> refine = {}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
    CameraRasterizer raster = refine.empty() ? CameraRasterizer(cam) : CameraRasterizer(cam, 3, refine);
    raster.recordTriangleIds();
    raster.recordClasses();
    for (const std::vector<Triangle>& chunk : chunks) raster.add(chunk);
    RasterResult r{raster.finish(), {}, {}};
    r.ids = raster.takeTriangleIds(), r.classes = raster.takeClasses();
    return r;
}

void requireSameRaster(const RasterResult& a, const RasterResult& b) {
    REQUIRE(a.set.size() == b.set.size());
    CHECK(a.set.pixel == b.set.pixel);
    CHECK(a.set.depth == b.set.depth);
    CHECK(a.set.position == b.set.position);
    CHECK(a.set.normal == b.set.normal);
    CHECK(a.ids == b.ids);
    CHECK(a.classes == b.classes);
}

}  // namespace

TEST_CASE("the z-buffer is the same for any thread count, layers and refinement included", "[receivers][camera]") {
    // Overlapping triangles of every size across the row bands, some through the near plane, and
    // pairs at exactly the same depth (the earlier one keeps the pixel, on any thread count).
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> coord(-5.0f, 5.0f), depth(-3.0f, 4.9f), size(0.01f, 3.0f);
    std::vector<std::vector<Triangle>> chunks(3);
    for (int i = 0; i < 900; ++i) {
        const glm::vec3 a(coord(rng), coord(rng), depth(rng));
        const float s = i % 10 == 0 ? 8.0f : size(rng);
        Triangle t{{a, a + glm::vec3(s, 0.3f * s, 0.2f), a + glm::vec3(0.1f * s, s, -0.3f)}, uint32_t(i % 3) << kTriangleClassShift};
        chunks[size_t(i) % 3].push_back(t);
        if (i % 3 == 0) chunks[size_t(i) % 3].push_back(Triangle{{t.v[0], t.v[2], t.v[1]}, 0});  // the same plane, flipped
    }
    CameraDesc cam = frontCamera(200, 150);
    cam.layers = 3;
    const RasterResult one = rasterizeWithThreads(chunks, cam, 1);
    REQUIRE(one.set.size() > 200 * 150);
    requireSameRaster(rasterizeWithThreads(chunks, cam, 2), one);
    requireSameRaster(rasterizeWithThreads(chunks, cam, 2), one);

    cam.layers = 1;
    std::vector<uint32_t> refine;
    for (uint32_t p = 5; p < 200 * 150; p += 13) refine.push_back(p);
    const RasterResult fine = rasterizeWithThreads(chunks, cam, 1, refine);
    REQUIRE(fine.set.size() > refine.size());
    requireSameRaster(rasterizeWithThreads(chunks, cam, 2, refine), fine);
}
