// glTF alphaMode MASK blockers (issue #15): textures from a bufferView, a file and a data: URI,
// TEXCOORD_n, wrap modes, KHR_texture_transform, cutoffs and factors. Baked through the whole
// pipeline: hpc and the reference give the same masks, Embree the same up to classified ties,
// the checkerboard its analytic visibility, and every alpha test the one an independent reading
// of the file's numbers gives. Instanced leaves share entries; an opaque blocker behind a cut-out
// still makes umbra.

#include "AreaSort.h"
#include "GltfAlphaFiles.h"
#include "TestScenes.h"

#include "bake/BakeCapture.h"
#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "bake/cast/PenumbraCaster.h"
#include "bake/rule/TieClassifier.h"
#include "procedural/Generators.h"
#include "stream/util/Npy.h"

#include <catch2/catch.hpp>

#include <glm/mat3x3.hpp>

#include <atomic>
#include <cmath>
#include <cstring>

using namespace penumbra;
using namespace penumbra::test;

namespace {

const json kLight = {{"type", "rect"}, {"center", {0, 3, 0}}, {"u", {0.6, 0, 0}}, {"v", {0, 0, 0.6}}, {"samples", 64}, {"sample_sets", 2}};

/// A 30 x 30 grid of points on the floor y = 0, facing up.
json floorPoints(const ScratchDir& dir) {
    writeFloorPoints(dir.path / "pts.npy", 30, -1.45f, 0.1f);
    return {{"type", "points"}, {"path", "pts.npy"}};
}

SceneDesc gltfScene(const ScratchDir& dir, const std::string& file, json light = kLight) {
    registerFileSourceTypes();
    registerProceduralGenerators();
    const json scene = {{"geometry", json::array({json{{"type", "file"}, {"path", file}}})},
                        {"lights", json::array({light})}, {"receivers", floorPoints(dir)}, {"output", "out.npy"}};
    return parseScene(scene, (dir.path / "scene.json").string());
}

BakeCapture bake(const SceneDesc& scene, const std::string& method, double* length = nullptr) {
    BakeCapture capture;
    capture.wantMasks = true;
    BakeSettings settings;
    settings.quiet = true, settings.threads = 2, settings.method = method, settings.capture = &capture;
    const json stats = runBake(scene, settings);
    if (length) *length = stats["epsilon"]["length"].get<double>();
    return capture;
}

/// hpc == reference bit for bit, Embree up to classified ties; @return the reference's bake.
BakeCapture requireMethodsAgree(const SceneDesc& scene) {
    double length = 1.0;
    const BakeCapture hpc = bake(scene, "hpc", &length);
    BakeCapture reference = bake(scene, "reference");
    const BakeCapture embree = bake(scene, "embree");
    REQUIRE(hpc.receivers.size() == reference.receivers.size());
    CHECK(hpc.masks.words == reference.masks.words);
    TriangleSourcePtr source = openSceneGeometry(scene);
    const std::vector<Triangle> triangles = readAll(*source);
    const TieClassifier classifier(triangles, {scene.options.epsilon, length}, TieClassifier::kDefaultUlps, scene.options.alphaTable);
    uint64_t nonTies = 0, mismatches = 0;
    const LightSamples& samples = reference.samples;
    for (size_t r = 0; r < reference.receivers.size(); ++r)
        for (int k = 0; k < samples.groupCount(); ++k)
            for (uint64_t d = embree.masks.row(r)[k] ^ reference.masks.row(r)[k]; d; d &= d - 1, ++mismatches) {
                const LightSampleGroup& g = samples.groups[k];
                const glm::dvec3 l(samples.position(int(reference.sampleSets[r]), int(g.first) + __builtin_ctzll(d)));
                const RelationVerdict v = classifier.classify(l, samples.w(g.light), glm::dvec3(reference.receivers.position[r]));
                if (!v.tie) ++nonTies, UNSCOPED_INFO(v.describe());
            }
    CHECK(nonTies == 0);
    CHECK(mismatches * 1000 <= uint64_t(reference.receivers.size()) * samples.sampleCount);
    return reference;
}

}  // namespace

TEST_CASE("glTF alpha: a checkerboard MASK quad gives its analytic visibility, its image in a view, a file or a data URI",
          "[alpha][gltf][embree]") {
    const int n = 8;
    std::vector<uint64_t> first;
    for (const std::string where : {"view", "file", "data"}) {
        INFO("image in a " << where);
        ScratchDir dir("gltf-alpha");
        writeCheckerQuad(dir / "quad.glb", n, where);
        const SceneDesc scene = gltfScene(dir, "quad.glb");
        const BakeCapture reference = requireMethodsAgree(scene);
        // Two triangles with distinct corner UVs: two entries after the built-in outlines.
        CHECK(scene.options.alphaTable->entries() == kBuiltinAlphaCount + 2);
        // The analytic answer: where the segment meets y = 1, the checker cell decides.
        const LightSamples& samples = reference.samples;
        uint64_t differ = 0, blocked = 0;
        for (size_t r = 0; r < reference.receivers.size(); ++r)
            for (int k = 0; k < samples.groupCount(); ++k)
                for (uint32_t j = 0; j < samples.groups[k].count; ++j) {
                    const glm::dvec3 l(samples.position(int(reference.sampleSets[r]), int(samples.groups[k].first + j)));
                    const glm::dvec3 p(reference.receivers.position[r]);
                    const double s = (1.0 - p.y) / (l.y - p.y);
                    const double cu = (p.x + s * (l.x - p.x) + 1) / 2 * n, cv = (p.z + s * (l.z - p.z) + 1) / 2 * n;
                    const bool inside = cu >= 0 && cu <= n && cv >= 0 && cv <= n;
                    const bool nearEdge = std::abs(cu - std::round(cu)) < 1e-6 || std::abs(cv - std::round(cv)) < 1e-6;
                    const bool analytic = inside && (int(std::floor(cu)) + int(std::floor(cv))) % 2 == 0;
                    const bool got = (reference.masks.row(r)[k] >> j) & 1;
                    blocked += got;
                    if (got != analytic && !nearEdge) ++differ;
                }
        CHECK(differ == 0);
        CHECK(blocked > 1000);
        if (first.empty()) first = reference.masks.words;
        else CHECK(reference.masks.words == first);
    }
}

namespace {

/// One random quad's material, as the test wrote it, for the independent alpha test.
struct RandomMaterial {
    int w = 1, h = 1;
    std::vector<uint8_t> rgba;
    double cutoff = 0.5, factor = 1.0;
    int wrapS = 10497, wrapT = 10497;
    bool transform = false;
    double offset[2] = {0, 0}, rotation = 0, scale[2] = {1, 1};
    std::array<glm::vec2, 4> uv;
};

int wrapped(int64_t i, int64_t n, int mode) {
    if (mode == 33071) return int(std::clamp<int64_t>(i, 0, n - 1));
    if (mode == 33648) {
        const int64_t m = ((i % (2 * n)) + 2 * n) % (2 * n);
        return int(m < n ? m : 2 * n - 1 - m);
    }
    return int(((i % n) + n) % n);
}

/// The alpha test read straight from the glTF numbers: the extension's T * R * S matrix, nearest
/// texel, alpha / 255 x factor >= cutoff. @return -1 near a texel edge (a tie).
int expectedOpaque(const RandomMaterial& m, glm::dvec2 uv) {
    glm::dvec3 x(uv, 1.0);
    if (m.transform) {
        const double c = std::cos(m.rotation), s = std::sin(m.rotation);
        const glm::dmat3 T(1, 0, 0, 0, 1, 0, m.offset[0], m.offset[1], 1);  // column-major
        const glm::dmat3 R(c, -s, 0, s, c, 0, 0, 0, 1);
        const glm::dmat3 S(m.scale[0], 0, 0, 0, m.scale[1], 0, 0, 0, 1);
        x = T * R * S * x;
    }
    const double fx = x.x * m.w, fy = x.y * m.h;
    if (std::abs(fx - std::round(fx)) < 1e-7 || std::abs(fy - std::round(fy)) < 1e-7) return -1;
    const int i = wrapped(int64_t(std::floor(fx)), m.w, m.wrapS), j = wrapped(int64_t(std::floor(fy)), m.h, m.wrapT);
    return m.rgba[(size_t(j) * m.w + i) * 4 + 3] / 255.0 * m.factor >= m.cutoff;
}

}  // namespace

TEST_CASE("glTF alpha: random MASK quads (cutoffs, factors, wraps, TEXCOORD_1, normalized UVs, KHR_texture_transform) agree in every method",
          "[alpha][gltf][embree]") {
    ScratchDir dir("gltf-alpha-soup");
    Rng rng(21);
    GlbBuilder b;
    std::vector<RandomMaterial> materials;
    const int wraps[3] = {10497, 33071, 33648};
    for (int q = 0; q < 24; ++q) {
        RandomMaterial m;
        m.w = 1 + int(rng.uniform() * 9), m.h = 1 + int(rng.uniform() * 9);
        for (int k = 0; k < m.w * m.h; ++k)
            for (int c = 0; c < 4; ++c) m.rgba.push_back(uint8_t(rng.uniform() * 256));
        m.cutoff = rng.uniform(0.1, 0.9), m.factor = rng.uniform(0.5, 1.5);
        m.wrapS = wraps[int(rng.uniform() * 3) % 3], m.wrapT = wraps[int(rng.uniform() * 3) % 3];
        m.transform = rng.uniform() < 0.6;
        m.offset[0] = rng.uniform(-1, 1), m.offset[1] = rng.uniform(-1, 1), m.rotation = rng.uniform(-3, 3);
        m.scale[0] = rng.uniform(0.5, 2), m.scale[1] = rng.uniform(0.5, 2);
        // A third of the quads store their UVs (then in [0, 1]) as normalized unsigned shorts.
        const bool quantized = q % 3 == 2;
        for (auto& t : m.uv) t = glm::vec2(float(rng.uniform(-1.5, 2.5)), float(rng.uniform(-1.5, 2.5)));
        if (quantized)
            for (auto& t : m.uv) t = glm::vec2(float(std::lround(rng.uniform() * 65535)) / 65535.0f, float(std::lround(rng.uniform() * 65535)) / 65535.0f);
        const int set = rng.uniform() < 0.5 ? 1 : 0;
        const int image = b.addImage(encodePngRgba(m.w, m.h, m.rgba), "image/png");
        b.append("samplers", {{"wrapS", m.wrapS}, {"wrapT", m.wrapT}});
        b.append("textures", {{"source", image}, {"sampler", q}});
        json material = maskMaterial(fmt::format("m{}", q), q, m.cutoff, m.factor, set);
        if (m.transform) {
            json t = {{"offset", {m.offset[0], m.offset[1]}}, {"rotation", m.rotation}, {"scale", {m.scale[0], m.scale[1]}}};
            // The extension's texCoord overrides the textureInfo's.
            if (set == 1) material["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = 0, t["texCoord"] = 1;
            material["pbrMetallicRoughness"]["baseColorTexture"]["extensions"]["KHR_texture_transform"] = t;
        }
        b.append("materials", material);
        const glm::vec3 c = randomIn(rng, {-1, 1, -1}, {1, 2, 1});
        const glm::vec3 e1 = randomIn(rng, glm::vec3(-0.6f), glm::vec3(0.6f)), e2 = randomIn(rng, glm::vec3(-0.6f), glm::vec3(0.6f));
        GltfQuad quad{{c - e1 - e2, c + e1 - e2, c + e1 + e2, c - e1 + e2}, m.uv, q, set, quantized};
        addNode(b, addQuadMesh(b, quad));
        materials.push_back(m);
    }
    for (int q = 0; q < 6; ++q) {  // opaque quads mixed in, without a material
        const glm::vec3 c = randomIn(rng, {-1, 0.5f, -1}, {1, 2.2f, 1});
        addNode(b, addQuadMesh(b, GltfQuad{{c, c + glm::vec3(0.3f, 0, 0), c + glm::vec3(0.3f, 0.1f, 0.3f), c + glm::vec3(0, 0.1f, 0.3f)}}));
    }
    b.write(dir / "soup.glb");
    const SceneDesc scene = gltfScene(dir, "soup.glb", {{"type", "rect"}, {"center", {0.2, 4, 0.1}}, {"u", {1.2, 0, 0}},
                                                        {"v", {0, 0, 1.2}}, {"samples", 128}, {"sample_sets", 4}});
    const BakeCapture reference = requireMethodsAgree(scene);
    CHECK(reference.masks.blockedCount() > 0);

    // Every alpha test at random barycentrics is the one the file's numbers give.
    TriangleSourcePtr source = openSceneGeometry(scene);
    const std::vector<Triangle> triangles = readAll(*source);
    REQUIRE(triangles.size() == 60);
    const AlphaTable& table = *scene.options.alphaTable;
    uint64_t checked = 0, opaque = 0;
    for (size_t t = 0; t < 48; ++t) {
        const RandomMaterial& m = materials[t / 2];
        const std::array<int, 3> corner = t % 2 == 0 ? std::array<int, 3>{0, 1, 2} : std::array<int, 3>{0, 2, 3};
        const uint32_t id = alphaIdOf(triangles[t].flags);
        for (int k = 0; k < 200; ++k) {
            double b0 = rng.uniform(), b1 = rng.uniform();
            if (b0 + b1 > 1) b0 = 1 - b0, b1 = 1 - b1;
            const double b2 = 1 - b0 - b1;
            const glm::dvec2 uv = b0 * glm::dvec2(m.uv[size_t(corner[0])]) + b1 * glm::dvec2(m.uv[size_t(corner[1])]) +
                                  b2 * glm::dvec2(m.uv[size_t(corner[2])]);
            const int expected = expectedOpaque(m, uv);
            if (expected < 0) continue;
            // A texture that came out all opaque or all clear has no id: opaque, or a non-casting triangle.
            const bool got = id ? table.lookup(id, b0, b1, b2).opaque : !(triangles[t].flags & kTriangleNoCast);
            CHECK(got == bool(expected));
            ++checked, opaque += expected;
        }
    }
    CHECK(checked > 9000);
    CHECK(opaque > 2000);
    CHECK(checked - opaque > 2000);
    for (size_t t = 48; t < 60; ++t) CHECK(triangles[t].flags == 0);
}

TEST_CASE("glTF alpha: umbra safety, an opaque quad behind a MASK quad still makes umbra, the MASK quad alone never",
          "[alpha][gltf][hpc]") {
    for (bool withOpaque : {false, true}) {
        ScratchDir dir("gltf-alpha-umbra");
        GlbBuilder b;
        b.addImage(encodePngRgba(64, 64, checkerRgba(64)), "image/png");
        b.append("textures", {{"source", 0}});
        b.append("materials", maskMaterial("fine checker", 0));
        GltfQuad cut{{glm::vec3(-3, 2, -3), glm::vec3(3, 2, -3), glm::vec3(3, 2, 3), glm::vec3(-3, 2, 3)}};
        cut.material = 0;
        addNode(b, addQuadMesh(b, cut));
        if (withOpaque) addNode(b, addQuadMesh(b, GltfQuad{{glm::vec3(-2, 1, -2), glm::vec3(2, 1, -2), glm::vec3(2, 1, 2), glm::vec3(-2, 1, 2)}}));
        b.write(dir / "umbra.glb");
        const SceneDesc scene = gltfScene(dir, "umbra.glb");
        TriangleSourcePtr source = openSceneGeometry(scene);
        std::vector<Triangle> tris = readAll(*source);
        sortByAreaDescending(tris);
        const ReceiverSet receivers = randomReceivers(4, 500, {-1, 0, -1}, {1, 0, 1});
        const LightSamples samples = generateLightSamples({rectLight({0, 4, 0}, {0.5, 0, 0}, {0, 0, 0.5}, 64, 2)}, 64, 7);
        const std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
        PenumbraCaster caster(samples, receivers, sets, scene.options, 1);
        caster.cast(tris);
        std::atomic<uint64_t> umbra{0}, partial{0};
        caster.finish([&](uint32_t, const uint64_t* words, bool full) {
            if (full) ++umbra;
            else if (words) ++partial;
        });
        INFO("with the opaque quad: " << withOpaque);
        CHECK(umbra == (withOpaque ? receivers.size() : 0));
        if (!withOpaque) CHECK(partial == receivers.size());
    }
}

TEST_CASE("glTF alpha: 1000 instances of a textured leaf share its entries, in every pass", "[alpha][gltf]") {
    ScratchDir dir("gltf-alpha-instances");
    GlbBuilder b;
    b.addImage(encodePngRgba(8, 8, checkerRgba(8)), "image/png");
    b.append("textures", {{"source", 0}});
    b.append("materials", maskMaterial("leaf", 0));
    b.append("materials", maskMaterial("leaf, same texture and cutoff", 0));
    GltfQuad card{{glm::vec3(0, 0, 0), glm::vec3(0.1f, 0, 0), glm::vec3(0.1f, 0, 0.1f), glm::vec3(0, 0, 0.1f)}};
    card.material = 0;
    const int leaf = addQuadMesh(b, card);
    card.material = 1;
    const int twin = addQuadMesh(b, card);
    for (int i = 0; i < 1000; ++i)
        addNode(b, i % 2 ? leaf : twin, {{"translation", {0.01 * (i % 37), 1 + 0.001 * i, 0.01 * (i / 37)}}});
    b.write(dir / "leaves.glb");
    const SceneDesc scene = gltfScene(dir, "leaves.glb");
    TriangleSourcePtr source = openSceneGeometry(scene);
    const std::vector<Triangle> first = readAll(*source);
    REQUIRE(first.size() == 2000);
    // One decoded texture and map, two entries (the two triangles' UVs), whatever the instance count.
    CHECK(scene.options.alphaTable->entries() == kBuiltinAlphaCount + 2);
    for (const Triangle& t : first) CHECK(alphaIdOf(t.flags) >= kBuiltinAlphaCount);
    auto same = [&](const std::vector<Triangle>& again) {
        return again.size() == first.size() && std::memcmp(again.data(), first.data(), first.size() * sizeof(Triangle)) == 0;
    };
    source->rewind();
    CHECK(same(readAll(*source)));
    CHECK(same(readAll(*openSceneGeometry(gltfScene(dir, "leaves.glb")))));  // another load, the same ids
}
