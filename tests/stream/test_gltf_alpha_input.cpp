// Bad glTF alpha textures (issue #15): a texture missing, unreadable, corrupt, truncated, of an
// absurd size or of an unsupported format, and a MASK material whose primitive lacks the UV set,
// each end a bake with exit 1 and one line naming the glTF file and the material (and the image),
// with no output and no temporary file. A texture that alone exceeds --memory-budget is refused
// before anything is decoded.

#include "CliRunner.h"
#include "GltfAlphaFiles.h"

#include "stream/util/Npy.h"

#include <catch2/catch.hpp>
#include <stb/stb_image_write.h>

#include <cstring>
#include <fstream>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// A scene over model.glb (geometry) with points on the floor, written to scene.json.
std::string writeScene(const ScratchDir& dir) {
    const float rows[12] = {0, 0, 0, 0, 1, 0, 0.5f, 0, 0.5f, 0, 1, 0};
    const uint64_t shape[2] = {2, 6};
    writeNpy(dir / "pts.npy", "<f4", shape, rows, sizeof(rows));
    const json scene = {{"geometry", listOf({{"type", "file"}, {"path", "model.glb"}})},
                        {"lights", listOf({{"type", "rect"}, {"center", {0, 3, 0}}, {"u", {0.5, 0, 0}}, {"v", {0, 0, 0.5}}})},
                        {"receivers", {{"type", "points"}, {"path", "pts.npy"}}},
                        {"output", "out.npy"}};
    std::ofstream(dir / "scene.json") << scene.dump();
    return dir / "scene.json";
}

/// model.glb: one MASK quad named "leaf" over texture 0 (image 0 as @p image describes it);
/// @p edit changes the document before it is written.
void writeModel(const ScratchDir& dir, const std::function<void(GlbBuilder&)>& image,
                const std::function<void(GlbBuilder&)>& edit = [](GlbBuilder&) {}) {
    GlbBuilder b;
    image(b);
    b.append("textures", {{"source", 0}});
    b.append("materials", maskMaterial("leaf", 0));
    GltfQuad q{{glm::vec3(-1, 1, -1), glm::vec3(1, 1, -1), glm::vec3(1, 1, 1), glm::vec3(-1, 1, 1)}};
    q.material = 0;
    addNode(b, addQuadMesh(b, q));
    edit(b);
    b.write(dir / "model.glb");
}

/// A PNG whose header claims @p w x @p h texels (its data is one 1 x 1 image's: it never decodes).
std::vector<uint8_t> pngClaiming(uint32_t w, uint32_t h) {
    std::vector<uint8_t> png = encodePngRgba(1, 1, {1, 2, 3, 4});
    for (int i = 0; i < 4; ++i) png[16 + i] = uint8_t(w >> (24 - 8 * i)), png[20 + i] = uint8_t(h >> (24 - 8 * i));
    return png;
}

/// The bake fails cleanly naming the model, the material and @p fragment, and leaves nothing behind.
void requireRefused(const ScratchDir& dir, const std::string& fragment, const std::string& extra = "") {
    const RunResult r = runPenumbra("bake " + writeScene(dir) + " -q --tmp " + dir.path.string() + extra);
    requireCleanError(r, fragment);
    CHECK_THAT(r.err, Catch::Contains("model.glb: material 0 (\"leaf\")"));
    CHECK_FALSE(std::filesystem::exists(dir / "out.npy"));
    CHECK_FALSE(hasTempFiles(dir.path));
}

}  // namespace

TEST_CASE("glTF alpha input: missing, corrupt, truncated, oversized and unsupported textures are one-line errors",
          "[alpha][gltf][cli]") {
    const std::vector<uint8_t> png = encodePngRgba(4, 4, checkerRgba(4));
    SECTION("a missing file") {
        ScratchDir dir("gltf-alpha-bad");
        writeModel(dir, [](GlbBuilder& b) { b.append("images", {{"uri", "missing.png"}}); });
        requireRefused(dir, "image 0 (\"missing.png\")");
    }
    SECTION("an unreadable file (a directory)") {
        ScratchDir dir("gltf-alpha-bad");
        std::filesystem::create_directory(dir / "dir.png");
        writeModel(dir, [](GlbBuilder& b) { b.append("images", {{"uri", "dir.png"}}); });
        requireRefused(dir, "image 0 (\"dir.png\")");
    }
    SECTION("a file outside the model's directory") {
        ScratchDir dir("gltf-alpha-bad");
        writeModel(dir, [](GlbBuilder& b) { b.append("images", {{"uri", "../outside.png"}}); });
        requireRefused(dir, "leaves the model's directory");
    }
    SECTION("corrupt PNG data") {
        ScratchDir dir("gltf-alpha-bad");
        std::vector<uint8_t> bad = png;
        for (size_t i = 40; i < bad.size(); ++i) bad[i] ^= 0x5a;
        writeModel(dir, [&](GlbBuilder& b) { b.addImage(bad, "image/png"); });
        requireRefused(dir, "image 0");
    }
    SECTION("a truncated bufferView") {
        ScratchDir dir("gltf-alpha-bad");
        writeModel(dir, [&](GlbBuilder& b) { b.addImage(std::vector<uint8_t>(png.begin(), png.begin() + 40), "image/png"); });
        requireRefused(dir, "image 0");
    }
    SECTION("absurd dimensions") {
        ScratchDir dir("gltf-alpha-bad");
        writeModel(dir, [&](GlbBuilder& b) { b.addImage(pngClaiming(1u << 20, 4), "image/png"); });
        requireRefused(dir, "texels on a side");
    }
    SECTION("zero dimensions") {
        ScratchDir dir("gltf-alpha-bad");
        writeModel(dir, [&](GlbBuilder& b) { b.addImage(pngClaiming(0, 4), "image/png"); });
        requireRefused(dir, "image 0");
    }
    SECTION("a KTX2 image") {
        ScratchDir dir("gltf-alpha-bad");
        const std::vector<uint8_t> ktx = {0xAB, 'K', 'T', 'X', ' ', '2', '0', 0xBB, 0x0D, 0x0A, 0x1A, 0x0A};
        writeModel(dir, [&](GlbBuilder& b) { b.addImage(ktx, "image/ktx2"); });
        requireRefused(dir, "is not a PNG or JPEG image (mimeType \"image/ktx2\")");
    }
    SECTION("a texture with only a KHR_texture_basisu image") {
        ScratchDir dir("gltf-alpha-bad");
        writeModel(dir, [&](GlbBuilder& b) { b.addImage(png, "image/png"); }, [](GlbBuilder& b) {
            b.json["textures"][0] = {{"extensions", {{"KHR_texture_basisu", {{"source", 0}}}}}};
        });
        requireRefused(dir, "texture 0: has only a KHR_texture_basisu image");
    }
    SECTION("a texCoord set the primitive lacks") {
        ScratchDir dir("gltf-alpha-bad");
        writeModel(dir, [&](GlbBuilder& b) { b.addImage(png, "image/png"); },
                   [](GlbBuilder& b) { b.json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = 3; });
        requireRefused(dir, "has no TEXCOORD_3");
    }
    SECTION("a texture that alone exceeds --memory-budget, refused before it is decoded") {
        ScratchDir dir("gltf-alpha-bad");
        writeModel(dir, [&](GlbBuilder& b) { b.addImage(pngClaiming(16384, 16384), "image/png"); });
        requireRefused(dir, "image 0: a 16384 x 16384 texture needs 2.03 GiB to decode; with the bake's baseline (48.0 MiB), --memory-budget 512 MiB is too small: at least 2128M is needed", " --memory-budget 512M");
    }
}

/// A 4 x 4 grey image without alpha channel: a JPEG or an RGB PNG.
std::vector<uint8_t> opaqueImage(bool jpeg) {
    const std::vector<uint8_t> rgb(4 * 4 * 3, 128);
    std::vector<uint8_t> out;
    auto sink = [](void* context, void* data, int size) {
        auto* o = static_cast<std::vector<uint8_t>*>(context);
        o->insert(o->end(), static_cast<uint8_t*>(data), static_cast<uint8_t*>(data) + size);
    };
    if (jpeg) stbi_write_jpg_to_func(sink, &out, 4, 4, 3, rgb.data(), 90);
    else stbi_write_png_to_func(sink, &out, 4, 4, 3, rgb.data(), 12);
    return out;
}

TEST_CASE("glTF alpha input: the factor alone, or a JPEG or RGB PNG (alpha 1), makes a MASK quad opaque or casting nothing",
          "[alpha][gltf][cli]") {
    for (const std::string image : {"none", "jpeg", "rgb png"})
    for (double factor : {0.2, 0.9}) {
        ScratchDir dir("gltf-alpha-factor");
        GlbBuilder b;
        int texture = -1;
        if (image != "none") {
            b.addImage(opaqueImage(image == "jpeg"), image == "jpeg" ? "image/jpeg" : "image/png");
            texture = b.append("textures", {{"source", 0}});
        }
        b.append("materials", maskMaterial("leaf", texture, 0.5, factor));
        GltfQuad q{{glm::vec3(-1, 1, -1), glm::vec3(1, 1, -1), glm::vec3(1, 1, 1), glm::vec3(-1, 1, 1)}};
        q.material = 0;
        addNode(b, addQuadMesh(b, q));
        b.write(dir / "model.glb");
        const RunResult r = runPenumbra("bake " + writeScene(dir) + " -q");
        REQUIRE(r.exitCode == 0);
        const NpyArray out = readNpy(dir / "out.npy");
        INFO("image " << image << ", factor " << factor);
        REQUIRE(out.data.size() == 2 * sizeof(float));
        float v[2];
        std::memcpy(v, out.data.data(), sizeof(v));
        CHECK(v[0] == (factor < 0.5 ? 1.0f : 0.0f));
        CHECK(v[1] == (factor < 0.5 ? 1.0f : 0.0f));
    }
}
