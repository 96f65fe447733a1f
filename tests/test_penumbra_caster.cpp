// PenumbraCaster's scheduling: tiles cast the prepared chunks from a ring, each at its own pace,
// with no barrier between chunks. Whatever the tile count, chunk size and thread count, the masks
// must be the reference's, and every blocker must be cast by every tile exactly once.

#include "TestScenes.h"

#include "procedural/GridGenerator.h"

#include <catch2/catch.hpp>
#include <tbb/task_arena.h>

using namespace penumbra;
using namespace penumbra::test;

TEST_CASE("caster: any tile count, chunk size and thread count gives the reference's masks", "[hpc][caster]") {
    GridParams p;
    p.cells = 6, p.levels = 2, p.size = 3, p.floorSize = 6;
    const std::vector<Triangle> tris = readAll(*makeGridSource(p));
    ReceiverSet receivers;
    addReceiversOnTriangles(receivers, std::vector<Triangle>(tris.begin(), tris.begin() + 2), 5, 300);
    addReceiversOnTriangles(receivers, std::vector<Triangle>(tris.begin() + 2, tris.end()), 6, 1);
    const LightSamples samples = generateLightSamples({rectLight({0.3, 4, 0.2}, {1.5, 0, 0}, {0, 0, 1.5}, 128, 4)}, 64, 7);
    const std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    const VisibilityMasks reference = castReference(samples, receivers, sets, tris, CastOptions().epsilon);
    REQUIRE(reference.blockedCount() > 0);
    REQUIRE(reference.blockedCount() < uint64_t(receivers.size()) * samples.sampleCount);

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
                    [&] { hpc = castHpc(samples, receivers, sets, tris, CastOptions(), tiles, chunk, &stats); });
                CHECK(hpc.words == reference.words);
                CHECK(stats.trianglesProcessed == tris.size());
                if (culled == ~0ull) culled = stats.trianglesCulledAtRoot;
                CHECK(stats.trianglesCulledAtRoot == culled);
            }
    }
}

TEST_CASE("caster: casters dropped mid-cast leave no task behind", "[hpc][caster]") {
    GridParams p;
    p.cells = 4, p.levels = 1, p.size = 3, p.floorSize = 6;
    const std::vector<Triangle> tris = readAll(*makeGridSource(p));
    ReceiverSet receivers;
    addReceiversOnTriangles(receivers, std::vector<Triangle>(tris.begin(), tris.begin() + 2), 3, 500);
    const LightSamples samples = generateLightSamples({rectLight({0, 4, 0}, {1, 0, 0}, {0, 0, 1}, 64, 2)}, 64, 7);
    const std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    const VisibilityMasks reference = castReference(samples, receivers, sets, tris, CastOptions().epsilon);
    REQUIRE(reference.blockedCount() > 0);
    // As when reading the replay throws between chunks: the destructor must wait for the tiles'
    // tasks, which point into the caster. Had one outlived it, it would write into freed memory
    // that the next casters reuse (and ASan would name it).
    tbb::task_arena(2).execute([&] {
        for (int round = 0; round < 20; ++round) {
            {
                PenumbraCaster dropped(samples, receivers, sets, CastOptions(), 8);
                for (size_t i = 0; i < tris.size() / 2; i += 3)
                    dropped.cast(std::span<const Triangle>(tris.data() + i, 3));
            }
            CHECK(castHpc(samples, receivers, sets, tris, CastOptions(), 8, 3).words == reference.words);
        }
    });
}
