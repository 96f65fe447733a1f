#pragma once
/// @file TileCaster.h
/// @brief Hierarchical penumbra casting over one tile of receivers: Laine & Aila 2005, Figure 3,
/// line by line (the line numbers are in the comments of TileCaster.cpp).
///
/// A tile owns a receiver hierarchy, a mask pool and the per-triangle scratch of the traversal.
/// Blockers arrive prepared (BlockerBatch.h: promoted to double, culled, with V_L per light);
/// castTriangle() descends the hierarchy with V_L and the group volumes V_Gk, decides receivers
/// with the sample mask table and the hard-shadow kernels, and keeps the umbra bits. A tile is
/// not thread-safe; PenumbraCaster runs tiles in parallel, one thread per tile at a time.

#include "bake/cast/CastOptions.h"
#include "bake/cast/HardShadowBlock.h"
#include "bake/light/Light.h"
#include "bake/cast/PenumbraVolume.h"
#include "bake/cast/SampleMaskTable.h"
#include "bake/cast/MaskPool.h"
#include "bake/cast/ReceiverHierarchy.h"

#include <cstdint>
#include <vector>

namespace penumbra {

/// @brief Counters of one tile (summed by PenumbraCaster::stats()).
struct TileStats {
    double buildSeconds = 0;  ///< hierarchy builds and rebuilds
    uint64_t rebuilds = 0, hardTests = 0, tableDecided = 0, alphaTests = 0, alphaRejected = 0;
    uint64_t alphaGroupTests = 0, alphaGroupsDecided = 0;
    uint64_t visits = 0;  ///< hierarchy nodes visited: with hardTests, the work the progress display counts
    size_t peakHierarchyBytes = 0, peakReceiverBytes = 0;
};

class TileCaster {
public:
    /// @param tables the sample mask table per light, or nullptr when the option is off
    TileCaster(const LightSamples& s, const CastOptions& o, const std::vector<SampleMaskTable>* t);

    /// @brief Bytes a tile holds whatever its receivers, for memory planning: the hard-shadow
    /// blocks of every sample set (80 bytes a sample), the group volumes, and its mask pool's
    /// last block. With 65,536 samples per light that is 6 MiB a light.
    static size_t fixedBytes(const LightSamples& samples);

    /// @brief Builds the hierarchy over the tile's receivers (optimization D off: every mask now).
    void build(std::vector<ReceiverInput> inputs);

    /// @brief Casts one prepared, valid blocker. @p lightVolumes and @p lightActive hold V_L and
    /// whether it is worth casting, per light.
    /// @return whether some light's V_L met the root box (a blocker no tile reaches was culled at
    /// the root).
    bool castTriangle(const BlockerTriangle& t, const PenumbraVolume* lightVolumes, const uint8_t* lightActive);

    const ReceiverHierarchy& hierarchy() const { return hierarchy_; }
    const MaskPool& pool() const { return pool_; }
    const TileStats& stats() const { return stats_; }
    /// @brief Work done so far, in units whose rate follows the time spent: nodes visited plus
    /// exact sample tests (the progress display's measure; ProgressEstimate.h).
    uint64_t work() const { return stats_.visits + stats_.hardTests; }

private:
    struct ActiveGroup {
        uint32_t group;
        uint32_t planes;
    };
    /// A receiver's table look-up, made by castLeaf() ahead of castReceiver().
    struct RowLookup {
        SampleMaskTable::Lookup result = SampleMaskTable::Lookup::Exact;
        SampleMaskTable::Rows rows;
    };

    void notePeaks();
    bool umbra() const { return options.umbraBits; }
    /// The per-triangle state that only a reached receiver needs, made on first use: the table's
    /// blocker coefficients, and V_Gk (for a blocker with table rows, deferred until it has reached
    /// options.groupVolumesAfter receivers). Most blockers never reach a receiver of a given tile.
    void prepareTableBlocker();
    void buildGroupVolumes();
    /// The hard-shadow blocks of group @p k in sample set @p set, with every block that holds a
    /// sample of @p needed built. Per-block laziness matters for small blockers, which touch a
    /// few receivers (so a few sets) and a few samples of each group.
    /// @return the group's first block and, in @p which, the blocks holding samples of @p needed.
    const HardShadowBlock* hardShadowBlocks(uint32_t set, uint32_t k, uint64_t needed, uint32_t& which);
    /// Whether every receiver in @p box is in front of the current closed triangle beyond its
    /// epsilon, so that castReceiver() would skip each of them (conservative: false when unsure).
    /// Only when V_L lacks the plane that cutInFront() appends (`--disable front-plane`, or a full
    /// volume).
    bool inFrontOfClosed(const Box& box) const;
    /// INTERSECTS() at the kernels' level: four planes per instruction with AVX2, two otherwise
    /// (the same answer and active planes either way).
    bool boxTest(const PenumbraVolume& v, const Box& box, uint32_t& active) const {
        return kernels.level == SimdLevel::Avx2 ? intersectsAvx2(v, box, active) : intersects(v, box, active);
    }
    /// Lines 35-36: whether node @p nodeIndex still holds a receiver out of umbra and meets V_L;
    /// @p planes (the parent's active V_L planes) loses the planes the node's box is inside of.
    bool enters(uint32_t nodeIndex, uint32_t& planes);
    /// Lines 37-54 for a node that enters(): the active groups, then its children or receivers.
    void visit(uint32_t nodeIndex, uint32_t planes, size_t groupsBegin, size_t groupsEnd);
    /// Lines 56-58 for a leaf's receivers, four at a time (LeafPrefilter.h), then castReceiver()
    /// for each that passes (with table rows, after all their look-ups, their cells prefetched).
    void castLeaf(uint32_t first, uint32_t count, uint32_t lightPlanes, size_t groupsBegin, size_t groupsEnd);
    /// Lines 59-75: one receiver that passed castLeaf()'s tests, at distance @p dist behind T's
    /// plane, against the active groups. @p looked is its table look-up when castLeaf() made it
    /// ahead (null: castReceiver() looks up itself, if it needs to); @p inFootprint, when given,
    /// holds every sample T can block for it (SampleMaskTable::footprint()).
    void castReceiver(uint32_t r, double dist, size_t groupsBegin, size_t groupsEnd, const RowLookup* looked,
                      const SampleMaskTable::Footprint* inFootprint);
    /// Whether the umbra words @p bits hold every group's bit (a loop: std::equal called memcmp
    /// for the usual single word, 1 % of GRIDS).
    bool fullWords(const uint64_t* bits) const {
        for (int w = 0; w < umbraWords; ++w)
            if (bits[w] != allGroupsBits[w]) return false;
        return true;
    }
    /// The active groups receiver @p r still needs (with open samples inside @p footprint, when
    /// given); returns how many of their samples are open.
    uint32_t gatherCandidates(uint32_t r, const glm::dvec3& p, bool pointTest, const SampleMaskTable::Footprint* footprint,
                              size_t groupsBegin, size_t groupsEnd);
    /// Of @p hits (the samples of group @p k, set @p set, whose hard-shadow volume holds @p p),
    /// the ones whose hit on the current alpha triangle passes the alpha test (AlphaRule.h); @p at
    /// is @p p relative to T's vertices.
    uint64_t alphaFilter(uint32_t set, uint32_t k, uint64_t hits, const glm::dvec3& p, const EdgeOffsets& at);

    const LightSamples& samples;
    const CastOptions& options;
    const std::vector<SampleMaskTable>* tables;  // per light, or nullptr when the option is off
    const AlphaTable& alphaTable;
    ReceiverHierarchy hierarchy_;
    MaskPool pool_;
    int groupCount, umbraWords;
    std::vector<uint64_t> allGroupsBits;  // umbra words with every group's bit set

    // Per-triangle state (Figure 3's "volumes-computed", split per light and per (set, group)).
    const BlockerTriangle* tri = nullptr;
    const PenumbraVolume* lightVolume = nullptr;
    /// Whether the current alpha triangle's test is an analytic outline that alphaFilter() runs
    /// four lanes at a time (AVX2 only), found on its first alpha test.
    enum : uint8_t { kOutlineUnknown, kOutlineYes, kOutlineNo } outline = kOutlineUnknown;
    AlphaOutline outlineOfTri;
    bool groupVolumesBuilt = false;
    /// Receivers past the leaf prefilter for the current light, counted until V_Gk are built (0:
    /// none yet, so the table's blocker is not prepared either).
    uint32_t leafReceivers = 0;
    uint32_t currentLight = 0;
    std::vector<PenumbraVolume> groupVolumes;
    // Hard-shadow volumes in blocks of four samples: group k's samples 4b..4b+3 are block
    // blockFirst[k] + b of a set; a set holds blocksPerSet blocks.
    HardShadowKernels kernels;
    std::vector<uint32_t> blockFirst;
    size_t blocksPerSet = 0;
    std::vector<HardShadowBlock> hardBlocks;  // [set][block]
    std::vector<uint32_t> hardReady;          // [set][group]: bit b set once block b is built
    std::vector<uint32_t> hardReadyList;
    std::vector<ActiveGroup> stack;
    std::vector<ActiveGroup> candidates;  // castReceiver(): the groups a receiver still needs
    SampleMaskTable::Blocker tableBlocker;  // the current triangle against the current light
    SampleMaskTable::SideCache sideCache;   // its plane's rows, when its plane cuts the light
    bool reachedRoot = false;  ///< the current triangle's V_L met the root box
    bool umbraChanged = false;  ///< visit(): some receiver's umbra bits changed below the current node

    TileStats stats_;
};

}  // namespace penumbra
