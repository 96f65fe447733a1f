// Adaptive antialiasing of camera receivers in two passes: the first pass's high-contrast pixels
// get a 2 x 2 sub-pixel pattern that equals the pixel centres of a twice-larger image, a second
// cast adds only those, and every method and thread count agrees bit for bit.

#include "TestScenes.h"

#include "bake/kinds/CameraKind.h"
#include "bake/output/ImageWriters.h"
#include "bake/Pipeline.h"
#include "bake/kinds/ReceiverKind.h"
#include "bake/Scene.h"
#include "bake/shading/SmoothShading.h"
#include "receivers/CameraReceivers.h"

#include <catch2/catch.hpp>

#include <fstream>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// A floor seen from straight above; a wall outside the view, lit from its far side by a small
/// light, casts a shadow whose edge crosses the image as a column near x = 16 of 48.
nlohmann::json edgeScene(int width, int height, bool antialias) {
    nlohmann::json receivers = {{"type", "camera"}, {"eye", {0, 6, 0}},   {"target", {0, 0, 0}}, {"up", {0, 0, -1}},
                                {"fov_deg", 40},    {"width", width},     {"height", height}};
    if (antialias) receivers["antialias"] = {{"threshold", 0.1}, {"samples", 4}};
    return {{"geometry", {{{"type", "obj"}, {"path", "scene.obj"}}}},
            {"lights",
             {{{"type", "rect"}, {"center", {-5, 4, 0}}, {"u", {0, 0, 0.2}}, {"v", {-0.14, -0.14, 0}}, {"radiance", 10},
               {"samples", 64}, {"sample_sets", 1}}}},
            {"receivers", receivers},
            {"output", "out/cam.exr"}};
}

void writeEdgeGeometry(const ScratchDir& dir) {
    std::ofstream obj(dir / "scene.obj");
    obj << "v -10 0 -10\nv 10 0 -10\nv 10 0 10\nv -10 0 10\nf 1 3 2\nf 1 4 3\n";  // floor, facing up
    obj << "v -3 0 -10\nv -3 2 -10\nv -3 2 10\nv -3 0 10\nf 5 6 7\nf 5 7 8\n";       // a wall at x = -3
}

struct Baked {
    ExrImage image;
    nlohmann::json stats;
    std::string bytes;
};

Baked bake(const ScratchDir& dir, const nlohmann::json& scene, const std::string& method = "hpc", int threads = 2,
           uint64_t memoryBudget = 0) {
    registerFileSourceTypes();
    SceneDesc desc = parseScene(scene, dir / "scene.json");
    BakeSettings settings;
    settings.quiet = true, settings.method = method, settings.threads = threads, settings.memoryBudget = memoryBudget;
    Baked b;
    b.stats = runBake(desc, settings);
    b.image = readExr(dir / "out/cam.exr");
    b.bytes = slurp(dir / "out/cam.exr");
    return b;
}

}  // namespace

TEST_CASE("antialiasing refines exactly the high-contrast pixels with the sub-pixels of a finer image", "[camera][antialias]") {
    ScratchDir dir("antialias");
    writeEdgeGeometry(dir);
    const int W = 48, H = 36;
    Baked coarse = bake(dir, edgeScene(W, H, false));
    Baked fine = bake(dir, edgeScene(2 * W, 2 * H, false));
    Baked aa = bake(dir, edgeScene(W, H, true));
    const std::vector<float>& v0 = coarse.image.channels["visibility.V"];

    // The pixels the rule picks, worked out here from the plain bake: |V - V_neighbour| > 0.1.
    std::vector<bool> expected(size_t(W) * H, false);
    int expectedCount = 0, minColumn = W, maxColumn = -1;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            REQUIRE(coarse.image.channels["A"][size_t(y) * W + x] == 1.f);  // the floor fills the view
            bool contrast = false;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    int nx = x + dx, ny = y + dy;
                    if (nx >= 0 && ny >= 0 && nx < W && ny < H)
                        contrast |= std::abs(double(v0[size_t(y) * W + x]) - v0[size_t(ny) * W + nx]) > 0.1;
                }
            expected[size_t(y) * W + x] = contrast;
            if (contrast) ++expectedCount, minColumn = std::min(minColumn, x), maxColumn = std::max(maxColumn, x);
        }
    // Along the shadow edge (a column band around x = 16) and nowhere in the flat regions.
    REQUIRE(expectedCount >= H);
    CHECK(minColumn >= 10);
    CHECK(maxColumn <= 22);
    CHECK(v0[size_t(H / 2) * W + 2] < 0.01f);       // umbra, left
    CHECK(v0[size_t(H / 2) * W + W - 3] == 1.f);    // lit, right
    CHECK(aa.stats["antialias"]["refined_pixels"] == expectedCount);
    CHECK(aa.stats["antialias"]["added_receivers"] == 4 * expectedCount);
    CHECK(aa.stats["antialias"]["refine_scan_time_s"].get<double>() > 0);  // the pipeline's key beside the kind's
    CHECK(aa.stats["receivers"] == W * H + 4 * expectedCount);

    // A refined pixel is the mean of the 2 x 2 finer pixels it covers (same surface points, same
    // light samples), summed in double in scanline order; the others are the plain bake's.
    const std::vector<float>& v2 = fine.image.channels["visibility.V"];
    const std::vector<float>& e2 = fine.image.channels["R"];
    int differs = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t px = size_t(y) * W + x;
            if (!expected[px]) {
                CHECK(aa.image.channels["visibility.V"][px] == v0[px]);
                CHECK(aa.image.channels["R"][px] == coarse.image.channels["R"][px]);
                continue;
            }
            double v = 0, e = 0;
            for (int sy = 0; sy < 2; ++sy)
                for (int sx = 0; sx < 2; ++sx) {
                    const size_t fpx = size_t(2 * y + sy) * (2 * W) + 2 * x + sx;
                    v += v2[fpx], e += e2[fpx];
                }
            CHECK(aa.image.channels["visibility.V"][px] == float(v / 4));
            CHECK(aa.image.channels["R"][px] == float(e / 4));
            CHECK(aa.image.channels["A"][px] == 1.f);
            CHECK(aa.image.channels["depth.Z"][px] == coarse.image.channels["depth.Z"][px]);  // the centre's depth
            differs += aa.image.channels["visibility.V"][px] != v0[px];
        }
    CHECK(differs > 0);  // antialiasing changed the edge pixels
}

TEST_CASE("antialiased camera bakes match the reference bit for bit and do not depend on threads", "[camera][antialias]") {
    ScratchDir dir("antialias-exact");
    writeEdgeGeometry(dir);
    nlohmann::json scene = edgeScene(320, 240, true);  // enough receivers for several memory tiles
    scene["lights"][0]["sample_sets"] = 4;  // sub-pixel receivers continue the receivers' set order
    Baked hpc1 = bake(dir, scene, "hpc", 1);
    Baked hpc2 = bake(dir, scene, "hpc", 2);
    Baked reference = bake(dir, scene, "reference", 2);
    REQUIRE(hpc1.stats["antialias"]["refined_pixels"].get<int>() > 0);
    CHECK(hpc1.bytes == hpc2.bytes);
    for (const char* key : {"refined_pixels", "added_receivers"}) CHECK(reference.stats["antialias"][key] == hpc1.stats["antialias"][key]);
    // Memory tiles: both passes replay the blockers once per tile, and the bytes do not change.
    // A budget for half the first pass's receivers per tile (or the smallest that works, if larger),
    // from the plan of a bake with the same thread count (each thread holds a row of depths).
    const nlohmann::json& plan = hpc2.stats["memory_plan"];
    const uint64_t half = plan["resident_bytes"].get<uint64_t>() +
                          plan["per_receiver_bytes"].get<uint64_t>() * hpc2.stats["receivers"].get<uint64_t>() / 2;
    Baked tiled = bake(dir, scene, "hpc", 2, std::max(half, plan["minimum_budget_bytes"].get<uint64_t>()));
    CHECK(tiled.stats["memory_plan"]["tiles"].get<int>() > 1);
    CHECK(tiled.bytes == hpc1.bytes);
    for (const auto& [name, values] : hpc1.image.channels) {
        INFO(name);
        CHECK(values == reference.image.channels[name]);
    }
}

TEST_CASE("an antialiased silhouette's R, G, B are premultiplied by its coverage, and its data layers are not", "[camera][antialias]") {
    // A straight colour with A < 1 gave every silhouette a bright halo over a background.
    ScratchDir dir("antialias-alpha");
    std::ofstream(dir / "scene.obj") << "v -1.3 0 -0.9\nv 1.1 0 -1.2\nv 1.2 0 1\nv -1 0 1.3\nf 1 3 2\nf 1 4 3\n";  // floor, facing up
    nlohmann::json scene = edgeScene(48, 36, true);
    scene["exr"] = {{"rgb", "visibility"}};  // R, G, B the visible fraction; irradiance.R/G/B the irradiance
    Baked grey = bake(dir, scene);
    scene["exr"] = {{"rgb", "irradiance"}};
    Baked colour = bake(dir, scene);
    const std::vector<float>& a = grey.image.channels["A"];
    REQUIRE(colour.image.channels["A"] == a);
    int partial = 0;
    for (size_t px = 0; px < a.size(); ++px) {
        INFO("pixel " << px << " A " << a[px]);
        if (a[px] == 0.f) CHECK(colour.image.channels["R"][px] == 0.f);
        if (a[px] == 0.f || a[px] == 1.f) continue;
        ++partial;
        const float v = grey.image.channels["visibility.V"][px], e = grey.image.channels["irradiance.R"][px];  // covered means
        CHECK(v == 1.f);  // nothing blocks the light: the data layer is not scaled by A
        CHECK(grey.image.channels["R"][px] == v * a[px]);
        CHECK(colour.image.channels["R"][px] == e * a[px]);
        CHECK(colour.image.channels["visibility.V"][px] == v);
    }
    CHECK(partial > 20);  // the quad's edges cross the view
}

TEST_CASE("antialias settings are checked with the key named", "[camera][antialias]") {
    ScratchDir dir("antialias-bad");
    writeEdgeGeometry(dir);
    auto errorFor = [&](const nlohmann::json& aa, int layers = 1) {
        nlohmann::json scene = edgeScene(8, 8, false);
        scene["receivers"]["antialias"] = aa;
        scene["receivers"]["layers"] = layers;
        return errorOf([&] {
            SceneDesc desc = parseScene(scene, dir / "scene.json");
            makeReceiverKind(desc.receivers, desc);
        });
    };
    CHECK(errorFor({{"samples", 5}}).find("receivers.antialias.samples") != std::string::npos);
    CHECK(errorFor({{"threshold", -1}}).find("receivers.antialias.threshold") != std::string::npos);
    CHECK(errorFor({{"treshold", 0.1}}).find("treshold") != std::string::npos);
    CHECK(errorFor({{"samples", 4}}, 2).find("one layer") != std::string::npos);
    CHECK(errorFor(true).find("receivers.antialias") != std::string::npos);
}

TEST_CASE("smooth shading finds its triangles by stream position as it would from recorded vertices", "[shading][camera]") {
    // A triangle soup seen by a camera: recording 8-byte ids and recovering the vertices in a
    // later stream-order pass (in chunks that cut the stream anywhere) gives the same factors.
    std::vector<Triangle> tris = triangleSoup(7, 400, {-2, -2, -2}, {2, 2, 2}, 1.5f);
    CameraDesc cam;
    cam.eye = {0, 1, 6}, cam.target = {0, 0, 0}, cam.width = 64, cam.height = 48;
    LightDesc light = rectLight({3, 4, 1}, {1, 0, 0}, {0, 0, 1}, 16, 1);
    CameraRasterizer byVertices(cam), byId(cam);
    byVertices.recordTriangles(), byId.recordTriangleIds();
    for (size_t i = 0; i < tris.size(); i += 37) {
        std::span<const Triangle> part(tris.data() + i, std::min<size_t>(37, tris.size() - i));
        byVertices.add(part), byId.add(part);
    }
    ReceiverSet a = byVertices.finish(), b = byId.finish();
    REQUIRE(a.size() > 1000);
    REQUIRE(a.position == b.position);
    VertexBend withVertices(byVertices.takeTriangles(), a.normal, lightDirections({light}));
    VertexBend withIds(lightDirections({light}));
    withIds.expectTriangleIds(byId.takeTriangleIds());
    for (size_t i = 0; i < tris.size(); i += 53)
        withIds.recover(std::span<const Triangle>(tris.data() + i, std::min<size_t>(53, tris.size() - i)));
    withVertices.add(tris), withIds.add(tris);
    CHECK(withIds.vertices() == withVertices.vertices());
    int shaded = 0;
    for (size_t r = 0; r < a.size(); ++r) {
        const glm::dvec3 p(a.position[r]), n(a.normal[r]);
        const double fa = withVertices.factor(r, p, n, 0), fb = withIds.factor(r, p, n, 0);
        CHECK(fa == fb);
        shaded += fa < 1.0;
    }
    CHECK(shaded > 0);
}

TEST_CASE("smooth shading does not bend across a crease: a lit box top keeps its full shading", "[shading][camera]") {
    // A cube lit from straight above, seen from above at an angle: its top corners also touch the
    // side faces, whose dot(l, n) is about zero; they are across a 90 degree crease and must not
    // darken the top. The sides, turned away from the light's centre, still bend.
    std::vector<Triangle> box;
    const glm::vec3 lo(-1, 0, -1), hi(1, 2, 1);
    addQuad(box, {lo.x, hi.y, lo.z}, {lo.x, hi.y, hi.z}, {hi.x, hi.y, hi.z}, {hi.x, hi.y, lo.z});  // top
    addQuad(box, {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z});  // front
    addQuad(box, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {hi.x, hi.y, hi.z}, {hi.x, lo.y, hi.z});  // right
    CameraDesc cam;
    cam.eye = {3, 5, 6}, cam.target = {0, 1, 0}, cam.width = 64, cam.height = 48;
    LightDesc light = rectLight({0, 8, 0}, {0.5, 0, 0}, {0, 0, -0.5}, 16, 1);
    CameraRasterizer raster(cam);
    raster.recordTriangleIds();
    raster.add(box);
    ReceiverSet r = raster.finish();
    VertexBend bend(lightDirections({light}));
    bend.expectTriangleIds(raster.takeTriangleIds());
    bend.recover(box);
    bend.add(box);
    int top = 0, side = 0;
    for (size_t i = 0; i < r.size(); ++i) {
        const double f = bend.factor(i, glm::dvec3(r.position[i]), glm::dvec3(r.normal[i]), 0);
        if (r.normal[i].y > 0.99f) {
            CHECK(f == 1.0);
            ++top;
        } else {
            CHECK(f < 1.0);  // a side: l_bend ~ 0 there, so the blend takes l_bend
            ++side;
        }
    }
    CHECK(top > 50);
    CHECK(side > 200);
}
