// The PNG preview of a vertex bake (MeshPreview.h): written beside the glTF and listed with it,
// the size asked for, shadows darker than lit floor, and the same bytes for any thread count.

#include "CliRunner.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <stb/stb_image.h>

#include <filesystem>
#include <fstream>
#include <set>

using namespace penumbra::test;

namespace {

/// An 8-bit RGB image read back with stb.
struct Rgb {
    int width = 0, height = 0;
    std::vector<uint8_t> pixels;
    int grey(int x, int y) const {
        const size_t i = 3 * (size_t(y) * size_t(width) + size_t(x));
        return (pixels[i] + pixels[i + 1] + pixels[i + 2]) / 3;
    }
};

Rgb readRgb(const std::string& path) {
    int w = 0, h = 0, channels = 0;
    unsigned char* data = stbi_load(path.c_str(), &w, &h, &channels, 3);
    REQUIRE(data != nullptr);
    Rgb image{w, h, std::vector<uint8_t>(data, data + size_t(w) * size_t(h) * 3)};
    stbi_image_free(data);
    return image;
}

/// The example's floor (6 x 6 at y = 0) and its blocker (y 1.2 to 1.5 over the centre), both
/// receivers, under a small light straight above; @p camera is receivers.camera when not null.
std::string writeScene(const ScratchDir& dir, const nlohmann::json& camera) {
    std::filesystem::copy_file(std::string(PENUMBRA_SOURCE_DIR) + "/examples/vertices-floor.glb", dir / "floor.glb",
                               std::filesystem::copy_options::overwrite_existing);
    nlohmann::json receivers = {{"type", "vertices"}, {"meshes", {0}}};
    if (!camera.is_null()) receivers["camera"] = camera;
    const nlohmann::json scene = {
        {"geometry", {{{"type", "glb"}, {"path", "floor.glb"}}}},
        {"lights", {{{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {0.5, 0, 0}}, {"v", {0, 0, 0.5}}, {"samples", 64}}}},
        {"receivers", receivers},
        {"output", "out/floor.glb"}};
    std::ofstream(dir / "scene.json") << scene.dump();
    return dir / "scene.json";
}

}  // namespace

TEST_CASE("vertices: a PNG preview from a framing view is written, listed and the same for any thread count", "[vertices][preview]") {
    ScratchDir dir("vertex-preview");
    const std::string scene = writeScene(dir, nullptr);
    RunResult one = runPenumbra("bake " + scene + " --threads 1 -o " + (dir / "one.glb") + " --stats " + (dir / "s.json"));
    INFO(one.err);
    REQUIRE(one.exitCode == 0);
    CHECK_THAT(one.err, Catch::Contains("-> " + (dir / "one.glb") + ", " + (dir / "one.png")));
    const nlohmann::json stats = nlohmann::json::parse(slurp(dir / "s.json"));
    CHECK(stats["outputs_written"] == nlohmann::json::array({dir / "one.glb", dir / "one.png", dir / "s.json"}));
    REQUIRE(runPenumbra("bake " + scene + " --quiet --threads 2 -o " + (dir / "two.glb")).exitCode == 0);
    CHECK(slurp(dir / "one.png") == slurp(dir / "two.png"));

    const Rgb image = readRgb(dir / "one.png");
    CHECK(image.width == 640);
    CHECK(image.height == 480);
    // The mesh fills a good part of the frame, in more than a few shades.
    const int background = image.grey(0, 0);
    size_t covered = 0;
    std::set<int> shades;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) {
            covered += image.grey(x, y) != background;
            shades.insert(image.grey(x, y));
        }
    CHECK(covered > size_t(image.width * image.height) / 8);
    CHECK(shades.size() > 20);
}

TEST_CASE("vertices: the preview takes receivers.camera, and shadowed floor is darker than lit floor", "[vertices][preview]") {
    ScratchDir dir("vertex-preview-camera");
    // From below, looking up: the floor hides the blocker, and its centre is in the blocker's
    // shadow. Image x is world x, image y is world -z; the floor's half-width 3 is 0.9 of the
    // half-frame (8 * tan 22.5 deg = 3.31).
    const std::string scene = writeScene(dir, {{"eye", {0, -8, 0}}, {"target", {0, 0, 0}}, {"up", {0, 0, 1}}, {"fov_deg", 45},
                                               {"width", 200}, {"height", 200}});
    RunResult r = runPenumbra("bake " + scene + " --quiet");
    INFO(r.err);
    REQUIRE(r.exitCode == 0);
    const Rgb image = readRgb(dir / "out/floor.png");
    REQUIRE(image.width == 200);
    REQUIRE(image.height == 200);
    const int umbra = image.grey(100, 100), lit = image.grey(170, 170), background = image.grey(1, 1);
    CHECK(umbra + 60 < lit);
    CHECK(umbra > background);  // the ambient term keeps the shadowed mesh above the background
    // The shadow is symmetric under a centred light: both sides of the centre agree.
    CHECK(std::abs(image.grey(100 - 40, 100) - image.grey(100 + 40, 100)) <= 8);
}

TEST_CASE("vertices: a bad receivers.camera is a one-line error naming the key", "[vertices][preview]") {
    ScratchDir dir("vertex-preview-errors");
    auto bake = [&](const nlohmann::json& camera) { return runPenumbra("bake " + writeScene(dir, camera) + " --quiet"); };
    requireCleanError(bake({{"eye", {0, 1, 0}}}), "receivers.camera.target");
    requireCleanError(bake({{"eye", {0, 1, 0}}, {"target", {0, 0, 0}}, {"fov", 30}}), "receivers.camera");
    requireCleanError(bake({{"eye", {0, 1, 0}}, {"target", {0, 1, 0}}}), "eye and target are the same point");
    requireCleanError(bake(5), "receivers.camera");
    CHECK(!std::filesystem::exists(dir / "out/floor.glb"));
}

TEST_CASE("vertices: a preview that would replace a texture of the input glTF is refused, and the texture kept", "[vertices][preview]") {
    // out wood.glb writes its preview to wood.png; the floor's (opaque, so never decoded) texture
    // was wood.png, and the bake replaced it with exit 0, leaving the input and the baked copy
    // pointing at the preview.
    ScratchDir dir("vertices-texture");
    const std::string texture = "\x89PNG\r\n\x1a\n not decoded: an opaque material's texture is never read";
    std::ofstream(dir / "wood.png", std::ios::binary) << texture;
    // Two triangles of a 4 x 4 floor at y = 0, positions in a base64 data URI.
    std::ofstream(dir / "floor.gltf") << R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
      "nodes": [{"name": "Floor", "mesh": 0}],
      "meshes": [{"name": "Floor", "primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
      "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
      "textures": [{"source": 0}], "images": [{"uri": "wood.png"}],
      "buffers": [{"byteLength": 72, "uri": "data:application/octet-stream;base64,AAAAwAAAAAAAAADAAAAAQAAAAAAAAABAAAAAQAAAAAAAAADAAAAAwAAAAAAAAADAAAAAwAAAAAAAAABAAAAAQAAAAAAAAABA"}],
      "bufferViews": [{"buffer": 0, "byteLength": 72}],
      "accessors": [{"bufferView": 0, "componentType": 5126, "count": 6, "type": "VEC3", "min": [-2, 0, -2], "max": [2, 0, 2]}]})";
    std::ofstream(dir / "scene.json") << R"({"geometry": [{"type": "gltf", "path": "floor.gltf"}],
        "lights": [{"type": "rect", "center": [0, 3, 0], "u": [1, 0, 0], "v": [0, 0, 1], "samples": 16}],
        "receivers": {"type": "vertices", "meshes": [0]}, "output": "wood.glb"})";
    const RunResult r = runPenumbra("bake " + dir / "scene.json" + " -q");
    requireCleanError(r, "wood.png: is also an input of this run");
    CHECK(slurp(dir / "wood.png") == texture);
    CHECK_FALSE(std::filesystem::exists(dir / "wood.glb"));
}
