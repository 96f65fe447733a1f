#pragma once
// Hand-made glTF files with alpha-tested (MASK) materials for the tests of glTF cut-outs: quads
// with corner UVs, PNG textures (stb_image_write) in a bufferView, a file or a data: URI.

#include "TestSupport.h"

#include "stream/GlbBuilder.h"
#include "stream/util/AtomicFile.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <nlohmann/json.hpp>

#include <array>
#include <cmath>
#include <string>
#include <vector>

namespace penumbra::test {

using json = nlohmann::json;

/// An n x n RGBA texture whose texel (i, j) has alpha 255 when i + j is even, else 0.
inline std::vector<uint8_t> checkerRgba(int n) {
    std::vector<uint8_t> rgba(size_t(n) * n * 4, 200);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) rgba[(size_t(j) * n + i) * 4 + 3] = (i + j) % 2 == 0 ? 255 : 0;
    return rgba;
}

/// A quad's corners and their UVs (TEXCOORD_set); other sets up to @p set get junk UVs.
struct GltfQuad {
    std::array<glm::vec3, 4> p;
    std::array<glm::vec2, 4> uv{glm::vec2(0, 0), glm::vec2(1, 0), glm::vec2(1, 1), glm::vec2(0, 1)};
    int material = -1;
    int set = 0;
    bool normalizedShort = false;  ///< UVs (in [0, 1]) as normalized UNSIGNED_SHORT
};

/// Adds @p q as a mesh of two indexed triangles (0, 1, 2) and (0, 2, 3); @return the mesh index.
inline int addQuadMesh(GlbBuilder& b, const GltfQuad& q) {
    const uint16_t indices[6] = {0, 1, 2, 0, 2, 3};
    json attributes = {{"POSITION", b.addAccessor(q.p.data(), 4, 5126, "VEC3")}};
    for (int s = 0; s <= q.set; ++s) {
        std::array<glm::vec2, 4> uv = q.uv;
        if (s != q.set)
            for (auto& t : uv) t = glm::vec2(0.37f, 0.61f);
        std::array<uint16_t, 8> quantized{};
        for (size_t k = 0; k < 8; ++k) quantized[k] = uint16_t(std::lround(uv[k / 2][int(k % 2)] * 65535.0f));
        attributes["TEXCOORD_" + std::to_string(s)] =
            q.normalizedShort ? b.addAccessor(quantized.data(), 4, 5123, "VEC2", true) : b.addAccessor(uv.data(), 4, 5126, "VEC2");
    }
    json primitive = {{"attributes", attributes}, {"indices", b.addAccessor(indices, 6, 5123, "SCALAR")}};
    if (q.material >= 0) primitive["material"] = q.material;
    return b.append("meshes", {{"primitives", json::array({primitive})}});
}

/// Adds a node drawing mesh @p mesh, in the default scene.
inline int addNode(GlbBuilder& b, int mesh, json extra = json::object()) {
    extra["mesh"] = mesh;
    const int node = b.append("nodes", std::move(extra));
    if (!b.json.contains("scenes")) b.json["scenes"] = json::array({json{{"nodes", json::array()}}}), b.json["scene"] = 0;
    b.json["scenes"][0]["nodes"].push_back(node);
    return node;
}

/// A MASK material over texture @p texture (or none when < 0).
inline json maskMaterial(const std::string& name, int texture, double cutoff = 0.5, double factor = 1.0, int texCoord = 0) {
    json pbr = {{"baseColorFactor", {1, 1, 1, factor}}};
    if (texture >= 0) pbr["baseColorTexture"] = {{"index", texture}, {"texCoord", texCoord}};
    return {{"name", name}, {"alphaMode", "MASK"}, {"alphaCutoff", cutoff}, {"pbrMetallicRoughness", pbr}};
}

/// One checkerboard-textured MASK quad [-1, 1]^2 at y = 1 (uv = ((x + 1) / 2, (z + 1) / 2)); the
/// image is stored as @p where says: "view" (a bufferView), "file" (tex.png next to @p path) or
/// "data" (a data: URI).
inline void writeCheckerQuad(const std::string& path, int n, const std::string& where) {
    GlbBuilder b;
    const std::vector<uint8_t> png = encodePngRgba(n, n, checkerRgba(n));
    int image = 0;
    if (where == "view") image = b.addImage(png, "image/png");
    else if (where == "file") {
        writeFileAtomically((std::filesystem::path(path).parent_path() / "tex.png").string(), png);
        image = b.append("images", {{"uri", "tex.png"}});
    } else {
        image = b.append("images", {{"uri", "data:image/png;base64," + encodeBase64(png)}});
    }
    b.append("samplers", {{"wrapS", 33071}, {"wrapT", 33071}, {"magFilter", 9729}});
    b.append("textures", {{"source", image}, {"sampler", 0}});
    b.append("materials", maskMaterial("checker", 0));
    GltfQuad q{{glm::vec3(-1, 1, -1), glm::vec3(1, 1, -1), glm::vec3(1, 1, 1), glm::vec3(-1, 1, 1)}};
    q.material = 0;
    addNode(b, addQuadMesh(b, q));
    b.write(path);
}

}  // namespace penumbra::test
