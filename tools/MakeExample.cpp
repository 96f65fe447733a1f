#include "MakeExample.h"

#include "stream/GlbBuilder.h"
#include "stream/util/Error.h"
#include "stream/util/PathText.h"

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include <cmath>
#include <cstdint>
#include <vector>

namespace penumbra {
namespace {

/// A small deterministic generator (splitmix64): the file must be the same bytes everywhere.
struct Mix {
    uint64_t state;
    double next() {
        uint64_t z = (state += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return double((z ^ (z >> 31)) >> 11) * 0x1p-53;
    }
    double in(double lo, double hi) { return lo + (hi - lo) * next(); }
};

/// The leaf-cluster texture: five leaves (outline |s| < w 4t(1 - t) along each leaf's axis) on a
/// transparent card, green where opaque.
std::vector<uint8_t> leafTexture(int n) {
    struct Leaf { glm::dvec2 base; double angle, length, width; };
    const Leaf leaves[] = {{{0.5, 0.95}, -1.57, 0.55, 0.32}, {{0.5, 0.75}, -2.3, 0.45, 0.3}, {{0.5, 0.75}, -0.84, 0.45, 0.3},
                           {{0.5, 0.55}, -2.8, 0.4, 0.28}, {{0.5, 0.55}, -0.34, 0.4, 0.28}};
    std::vector<uint8_t> rgba(size_t(n) * n * 4, 0);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const glm::dvec2 uv((i + 0.5) / n, (j + 0.5) / n);
            bool inside = false;
            for (const Leaf& l : leaves) {
                const glm::dvec2 axis(std::cos(l.angle), std::sin(l.angle)), d = uv - l.base;
                const double t = glm::dot(d, axis) / l.length, s = (d.x * axis.y - d.y * axis.x) / l.length;
                inside = inside || (t > 0 && t < 1 && std::abs(s) < l.width * 4 * t * (1 - t));
            }
            uint8_t* p = &rgba[(size_t(j) * n + i) * 4];
            p[0] = 60, p[1] = uint8_t(110 + 60 * uv.y), p[2] = 40, p[3] = inside ? 255 : 0;
        }
    return rgba;
}

/// An open hexagonal prism from @p a to @p b of radius @p r, as a mesh without material.
int prismMesh(GlbBuilder& b, glm::vec3 a, glm::vec3 top, float r) {
    std::vector<glm::vec3> p;
    std::vector<uint16_t> idx;
    for (int k = 0; k < 6; ++k) {
        const float angle = float(k) * 1.0471976f;
        const glm::vec3 o(r * std::cos(angle), 0, r * std::sin(angle));
        p.push_back(a + o), p.push_back(top + o * 0.6f);
    }
    for (uint16_t k = 0; k < 6; ++k) {
        const uint16_t a0 = uint16_t(2 * k), t0 = uint16_t(2 * k + 1), a1 = uint16_t(2 * ((k + 1) % 6)), t1 = uint16_t(a1 + 1);
        idx.insert(idx.end(), {a0, t0, a1, a1, t0, t1});
    }
    const nlohmann::json attributes = {{"POSITION", b.addAccessor(p.data(), p.size(), 5126, "VEC3")}};
    return b.append("meshes", {{"name", "trunk"},
                               {"primitives", nlohmann::json::array({{{"attributes", attributes},
                                                                       {"indices", b.addAccessor(idx.data(), idx.size(), 5123, "SCALAR")}}})}});
}

/// The leaf card: a 0.7 x 0.7 quad in its xz plane, UVs over the whole texture, material 0.
int cardMesh(GlbBuilder& b) {
    const glm::vec3 p[4] = {{-0.35f, 0, -0.35f}, {0.35f, 0, -0.35f}, {0.35f, 0, 0.35f}, {-0.35f, 0, 0.35f}};
    const glm::vec2 uv[4] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    const uint16_t idx[6] = {0, 1, 2, 0, 2, 3};
    const nlohmann::json attributes = {{"POSITION", b.addAccessor(p, 4, 5126, "VEC3")}, {"TEXCOORD_0", b.addAccessor(uv, 4, 5126, "VEC2")}};
    return b.append("meshes", {{"name", "leaf card"},
                               {"primitives", nlohmann::json::array({{{"attributes", attributes},
                                                                       {"indices", b.addAccessor(idx, 6, 5123, "SCALAR")},
                                                                       {"material", 0}}})}});
}

}  // namespace

void writeGltfTree(const std::string& path, int cards) {
    GlbBuilder b;
    b.addImage(encodePngRgba(128, 128, leafTexture(128)), "image/png");
    b.append("samplers", {{"wrapS", 33071}, {"wrapT", 33071}});
    b.append("textures", {{"source", 0}, {"sampler", 0}});
    b.append("materials", {{"name", "leaves"}, {"alphaMode", "MASK"}, {"alphaCutoff", 0.5}, {"doubleSided", true},
                           {"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}});
    nlohmann::json roots = nlohmann::json::array();
    roots.push_back(b.append("nodes", {{"name", "trunk"}, {"mesh", prismMesh(b, {0, 0, 0}, {0, 2.4f, 0}, 0.14f)}}));
    const int card = cardMesh(b);
    Mix rng{15};
    for (int i = 0; i < cards; ++i) {
        // Cards fill an ellipsoidal crown, denser near its surface, turned every way.
        glm::dvec3 d;
        do d = {rng.in(-1, 1), rng.in(-1, 1), rng.in(-1, 1)};
        while (glm::dot(d, d) > 1 || glm::dot(d, d) < 0.15);
        glm::dvec4 q(rng.in(-1, 1), rng.in(-1, 1), rng.in(-1, 1), rng.in(-1, 1));
        q /= std::sqrt(glm::dot(q, q));
        roots.push_back(b.append("nodes", {{"mesh", card},
                                           {"translation", {1.8 * d.x, 3.0 + 1.1 * d.y, 1.8 * d.z}},
                                           {"rotation", {q.x, q.y, q.z, q.w}}}));
    }
    b.json["scenes"] = nlohmann::json::array({{{"nodes", roots}}});
    b.json["scene"] = 0;
    b.write(path);
}

CLI::App* addMakeExampleCommand(CLI::App& app, MakeExampleOptions& options) {
    CLI::App* cmd = app.add_subcommand("make-example", "write a generated example file: penumbra make-example gltf-tree -o FILE.glb");
    cmd->add_option("name", options.name, "the example: gltf-tree (a glTF tree with alpha-tested leaf cards)")->required();
    cmd->add_option("-o,--output", options.output, "the binary glTF (.glb) to write")->required();
    return cmd;
}

void runMakeExample(const MakeExampleOptions& options) {
    if (options.name != "gltf-tree") throw InputError(fmt::format("make-example: unknown example \"{}\" (known: gltf-tree)", options.name));
    // The example is a binary glTF: another extension (x.obj) got GLB bytes under a name that says otherwise.
    if (lowercaseExtension(options.output) != ".glb")
        throw InputError(fmt::format("{}: make-example gltf-tree writes a binary glTF; give the output a .glb extension", options.output));
    writeGltfTree(options.output);
}

}  // namespace penumbra
