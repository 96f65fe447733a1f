#pragma once
/// @file AlphaScenes.h
/// @brief Cut-out test scenes shared by the alpha tests: textured quad soups, the tree-and-flowers
/// scene of analytic outlines, and their helpers.

#include "TestScenes.h"

#include "procedural/FlowerGenerator.h"
#include "procedural/TreeGenerator.h"
#include "stream/AlphaTable.h"
#include "stream/TriangleSource.h"

#include <catch2/catch.hpp>

#include <cmath>
#include <memory>

namespace penumbra::test {

/// A quad a, b, c, d as two alpha triangles with corner UVs @p uv (one per corner), id per half.
inline void addAlphaQuad(std::vector<Triangle>& out, AlphaTable& table, uint32_t map, const glm::vec3 (&p)[4],
                  const glm::dvec2 (&uv)[4]) {
    const uint32_t lower = table.addEntry({map, {uv[0], uv[1], uv[2]}});
    const uint32_t upper = table.addEntry({map, {uv[0], uv[2], uv[3]}});
    out.push_back({{p[0], p[1], p[2]}, withAlphaId(0, lower)});
    out.push_back({{p[0], p[2], p[3]}, withAlphaId(0, upper)});
}

/// An n x n checkerboard texture, texel (i, j) opaque when i + j is even.
inline AlphaMap checkerboard(uint32_t n) {
    std::vector<uint8_t> opaque(size_t(n) * n);
    for (uint32_t j = 0; j < n; ++j)
        for (uint32_t i = 0; i < n; ++i) opaque[j * n + i] = (i + j) % 2 == 0;
    return AlphaMap::texture(n, n, opaque);
}

/// A random texture thresholded at a random cutoff, with random wraps and transform.
inline AlphaMap randomTexture(Rng& rng) {
    const uint32_t w = 1 + uint32_t(rng.uniform() * 12), h = 1 + uint32_t(rng.uniform() * 12);
    const double cutoff = rng.uniform();
    std::vector<uint8_t> opaque(size_t(w) * h);
    for (auto& o : opaque) o = rng.uniform() >= cutoff;
    AlphaMap m = AlphaMap::texture(w, h, opaque);
    const AlphaWrap wraps[3] = {AlphaWrap::Repeat, AlphaWrap::Clamp, AlphaWrap::Mirror};
    m.wrapS = wraps[int(rng.uniform() * 3) % 3], m.wrapT = wraps[int(rng.uniform() * 3) % 3];
    const double angle = rng.uniform(-1, 1), sx = rng.uniform(0.5, 2), sy = rng.uniform(0.5, 2);
    m.transform = {sx * std::cos(angle), -sy * std::sin(angle), rng.uniform(-1, 1),
                   sx * std::sin(angle), sy * std::cos(angle), rng.uniform(-1, 1)};
    return m;
}

/// Random alpha quads (random textures, UVs beyond [0, 1]) over a floor, with opaque blockers
/// mixed in when @p opaque > 0; receivers on the floor and on the blockers.
struct AlphaSoup {
    std::shared_ptr<AlphaTable> table = std::make_shared<AlphaTable>();
    std::vector<Triangle> tris;
    ReceiverSet receivers;

    AlphaSoup(uint64_t seed, int quads, int opaque) {
        Rng rng(seed);
        for (int q = 0; q < quads; ++q) {
            const uint32_t map = table->addMap(randomTexture(rng));
            const glm::vec3 c = randomIn(rng, {-2, 1, -2}, {2, 2.5f, 2});
            const glm::vec3 e1 = randomIn(rng, glm::vec3(-0.8f), glm::vec3(0.8f));
            const glm::vec3 e2 = randomIn(rng, glm::vec3(-0.8f), glm::vec3(0.8f));
            const glm::vec3 p[4] = {c - e1 - e2, c + e1 - e2, c + e1 + e2, c - e1 + e2};
            glm::dvec2 uv[4];
            for (auto& t : uv) t = {rng.uniform(-1.5, 2.5), rng.uniform(-1.5, 2.5)};
            addAlphaQuad(tris, *table, map, p, uv);
        }
        std::vector<Triangle> extra = triangleSoup(seed + 1, opaque, {-2, 0.8f, -2}, {2, 2.8f, 2}, 0.8f);
        std::vector<Triangle> floor;
        addQuad(floor, {-4, 0, -4}, {4, 0, -4}, {4, 0, 4}, {-4, 0, 4});
        addReceiversOnTriangles(receivers, floor, seed + 2, 400);
        addReceiversOnTriangles(receivers, tris, seed + 3, 2);
        tris.insert(tris.end(), extra.begin(), extra.end());
        tris.insert(tris.end(), floor.begin(), floor.end());
    }
};

/// A small tree (leaf cut-outs, kAlphaLeaf*) over 30 flowers (petal cut-outs, kAlphaPetal*).
inline std::vector<Triangle> leavesAndPetals() {
    TreeParams tp;
    tp.depth = 2, tp.leavesPerBranch = 6, tp.leafSize = 0.4;
    std::vector<Triangle> tree = buildTree(tp);
    uint64_t leaves = 0;
    for (const Triangle& t : tree)
        if (alphaIdOf(t.flags)) {
            ++leaves;
            CHECK((alphaIdOf(t.flags) == kAlphaLeafLower || alphaIdOf(t.flags) == kAlphaLeafUpper));
            CHECK((t.flags & kTriangleAlphaMatte));
        }
    CHECK(leaves == 2 * 9 * 6);
    FlowerParams fp;
    fp.placement.count = 30;
    fp.placement.area = {-1, -1, 1, 1};
    fp.petalLength = {0.2, 0.3};
    std::vector<Triangle> scene = readAll(*makeFlowerSource(fp));
    for (const Triangle& t : scene) CHECK(alphaIdOf(t.flags) <= kAlphaPetalUpper);
    for (Triangle t : tree) {
        for (auto& v : t.v) v = v * 0.6f + glm::vec3(0, 0.4f, 0);
        scene.push_back(t);
    }
    return scene;
}

inline CastOptions withTable(CastOptions o, std::shared_ptr<const AlphaTable> table) {
    o.alphaTable = std::move(table);
    return o;
}

}  // namespace penumbra::test
