// PenumbraCaster's scheduling: tiles cast the prepared chunks from a ring, each at its own pace,
// with no barrier between chunks. Whatever the tile count, chunk size and thread count, the masks
// must be the reference's, and every blocker must be cast by every tile exactly once.

#include "TestScenes.h"

#include "procedural/GridGenerator.h"

#include <catch2/catch.hpp>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <numeric>
#include <random>

using namespace penumbra;
using namespace penumbra::test;

namespace {

/// Perforated grids over a floor, receivers on the floor and on the bars, and the reference's
/// masks, which must hold blocked and unblocked relations.
struct GridCase {
    std::vector<Triangle> tris;
    ReceiverSet receivers;
    LightSamples samples;
    std::vector<uint32_t> sets;
    VisibilityMasks reference;

    GridCase(int cells, int levels, int floorReceivers, const LightDesc& light) {
        GridParams p;
        p.cells = cells, p.levels = levels, p.size = 3, p.floorSize = 6;
        tris = readAll(*makeGridSource(p));
        addReceiversOnTriangles(receivers, std::vector<Triangle>(tris.begin(), tris.begin() + 2), 5, floorReceivers);
        addReceiversOnTriangles(receivers, std::vector<Triangle>(tris.begin() + 2, tris.end()), 6, 1);
        samples = generateLightSamples({light}, 64, 7);
        sets = assignSets(receivers, samples.sets);
        reference = castReference(samples, receivers, sets, tris, receiverEpsilonOf(CastOptions()));
        REQUIRE(reference.blockedCount() > 0);
        REQUIRE(reference.blockedCount() < uint64_t(receivers.size()) * samples.sampleCount);
    }
};

}  // namespace

TEST_CASE("caster: any tile count, chunk size and thread count gives the reference's masks", "[hpc][caster]") {
    const GridCase g(6, 2, 300, rectLight({0.3, 4, 0.2}, {1.5, 0, 0}, {0, 0, 1.5}, 128, 4));

    for (int tiles : {1, 2, 5, 16}) {
        // Root culls depend on the tiles' boxes, so they are compared per tile count.
        uint64_t culled = ~0ull;
        // Chunks of one blocker publish far faster than tiles cast them: the ring is full all the
        // time and the calling thread keeps helping. Chunks larger than the scene use one slot.
        for (size_t chunk : {size_t(1), size_t(7), size_t(4096)})
            for (int threads : {1, 2, 4}) {
                INFO("tiles " << tiles << ", chunk " << chunk << ", threads " << threads);
                CastStats stats;
                VisibilityMasks hpc;
                tbb::task_arena(threads).execute(
                    [&] { hpc = castHpc(g.samples, g.receivers, g.sets, g.tris, CastOptions(), tiles, chunk, &stats); });
                CHECK(hpc.words == g.reference.words);
                CHECK(stats.trianglesProcessed == g.tris.size());
                if (culled == ~0ull) culled = stats.trianglesCulledAtRoot;
                CHECK(stats.trianglesCulledAtRoot == culled);
            }
    }
}

TEST_CASE("caster: the root-cull count does not depend on how the tiles are timed", "[hpc][caster]") {
    // The last tile to cast a chunk counts the blockers no tile's root reached, reading every
    // tile's flags; the slot must stay held until then. Released any earlier, the feeding thread
    // refilled it mid-count and the count changed from run to run under load (CI, 2026-12-02).
    // A pause before each count (a test hook) opens that window wide on every chunk.
    const GridCase g(6, 2, 300, rectLight({0.3, 4, 0.2}, {1.5, 0, 0}, {0, 0, 1.5}, 64, 2));
    CastOptions paused;
    paused.countDelayForTestsUs = 300;
    for (size_t chunk : {size_t(16), size_t(256)}) {
        INFO("chunk " << chunk);
        CastStats plain, delayed;
        VisibilityMasks a, b;
        tbb::task_arena(2).execute([&] {
            a = castHpc(g.samples, g.receivers, g.sets, g.tris, CastOptions(), 8, chunk, &plain);
            b = castHpc(g.samples, g.receivers, g.sets, g.tris, paused, 8, chunk, &delayed);
        });
        CHECK(delayed.trianglesCulledAtRoot == plain.trianglesCulledAtRoot);
        CHECK(b.words == g.reference.words);
        CHECK(a.words == g.reference.words);
    }
}

TEST_CASE("caster: casters dropped mid-cast leave no task behind", "[hpc][caster]") {
    const GridCase g(4, 1, 500, rectLight({0, 4, 0}, {1, 0, 0}, {0, 0, 1}, 64, 2));
    // As when reading the replay throws between chunks: the destructor must wait for the tiles'
    // tasks, which point into the caster. Had one outlived it, it would write into freed memory
    // that the next casters reuse (and ASan would name it).
    tbb::task_arena(2).execute([&] {
        for (int round = 0; round < 20; ++round) {
            {
                PenumbraCaster dropped(g.samples, g.receivers, g.sets, CastOptions(), 8);
                for (size_t i = 0; i < g.tris.size() / 2; i += 3)
                    dropped.cast(std::span<const Triangle>(g.tris.data() + i, 3));
            }
            CHECK(castHpc(g.samples, g.receivers, g.sets, g.tris, CastOptions(), 8, 3).words == g.reference.words);
        }
    });
}

namespace {

/// partitionReceivers() as it was before its halves ran in parallel: one recursion, parts
/// appended in order. The parallel form must give the same parts (shards depend on it).
std::vector<std::vector<uint32_t>> serialPartition(const ReceiverSet& receivers, std::vector<uint32_t> order, int count) {
    std::vector<std::vector<uint32_t>> parts;
    auto split = [&](auto&& self, size_t begin, size_t end, int pieces) -> void {
        if (pieces <= 1 || end - begin <= 1) {
            parts.emplace_back(order.begin() + begin, order.begin() + end);
            std::sort(parts.back().begin(), parts.back().end());
            return;
        }
        glm::vec3 lo(INFINITY), hi(-INFINITY);
        for (size_t i = begin; i < end; ++i)
            lo = glm::min(lo, receivers.position[order[i]]), hi = glm::max(hi, receivers.position[order[i]]);
        const glm::vec3 e = hi - lo;
        const int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
        const int left = pieces / 2;
        const size_t mid = begin + (end - begin) * left / pieces;
        std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end, [&](uint32_t a, uint32_t b) {
            const float pa = receivers.position[a][axis], pb = receivers.position[b][axis];
            return pa < pb || (pa == pb && a < b);
        });
        self(self, begin, mid, left);
        self(self, mid, end, pieces - left);
    };
    split(split, 0, order.size(), std::max(1, count));
    return parts;
}

}  // namespace

TEST_CASE("receivers split into the same tiles on any thread count", "[caster][tiles]") {
    // 200,000 receivers (the halves run in parallel above 65,536), many on a coarse lattice so
    // that coordinates tie, and sets too small to split into every part.
    std::mt19937 rng(5);
    std::uniform_int_distribution<int> cell(0, 40);
    std::uniform_real_distribution<float> any(-3.f, 3.f);
    ReceiverSet big;
    for (int i = 0; i < 200000; ++i)
        big.position.push_back(i % 3 == 0 ? glm::vec3(cell(rng), 0.f, cell(rng)) * 0.1f : glm::vec3(any(rng), any(rng) * 0.1f, any(rng)));
    std::vector<uint32_t> ids(big.position.size());
    std::iota(ids.begin(), ids.end(), 0u);
    std::shuffle(ids.begin(), ids.end(), rng);
    ids.resize(170000);  // a subset, in no order (as a refinement's or a shard's receivers)
    for (const int count : {1, 2, 3, 8, 13}) {
        const auto expected = serialPartition(big, ids, count);
        CHECK(expected.size() == size_t(count));
        for (const int threads : {1, 2}) {
            tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
            CHECK(partitionReceivers(big, ids, count) == expected);
        }
    }
    ReceiverSet few;
    few.position = {glm::vec3(0.f), glm::vec3(1.f, 0.f, 0.f)};
    for (const std::vector<uint32_t>& small : {std::vector<uint32_t>{}, std::vector<uint32_t>{1}, std::vector<uint32_t>{1, 0}})
        for (const int count : {1, 2, 8}) CHECK(partitionReceivers(few, small, count) == serialPartition(few, small, count));
}
