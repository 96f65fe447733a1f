#include "bake/cast/TileCaster.h"

#include "bake/cast/LeafPrefilter.h"
#include "bake/cast/OutlineTest.h"

#include "bake/rule/AlphaBound.h"
#include "bake/rule/AlphaRule.h"
#include "stream/util/Timer.h"

#include <algorithm>

namespace penumbra {
namespace {

constexpr uint32_t kAllPlanes = ~0u;  // "ALL": masked by the volume's own plane count when used
/// A split blocker's table look-up (four lines) costs about as much as this many exact tests
/// (docs/performance.md, "Blockers whose plane cuts the light"); with fewer open samples in the
/// groups whose V_Gk holds the receiver, the exact tests decide them.
constexpr uint32_t kSplitTableMinimumBits = 48;
/// A group's alpha bound (AlphaBound.h) costs about as much as this many per-hit alpha tests
/// (docs/performance.md, "Alpha tests by group"); a group with fewer candidates tests its hits.
constexpr int kAlphaBoundMinimumBits = 32;

}  // namespace

TileCaster::TileCaster(const LightSamples& s, const CastOptions& o, const std::vector<SampleMaskTable>* t)
    : samples(s), options(o), tables(t), alphaTable(alphaTableOf(o)), hierarchy_(o.hierarchy, s.groupCount()), pool_(s.groupCount()),
      groupCount(s.groupCount()), umbraWords((s.groupCount() + 63) / 64), kernels(hardShadowKernels(o.simd)) {
    allGroupsBits.assign(umbraWords, 0);
    for (int k = 0; k < groupCount; ++k) allGroupsBits[k >> 6] |= 1ull << (k & 63);
    groupVolumes.resize(groupCount);
    for (const LightSampleGroup& g : s.groups) {
        blockFirst.push_back(uint32_t(blocksPerSet));
        blocksPerSet += hardShadowBlocksFor(g.count);
    }
    hardBlocks.resize(size_t(s.sets) * blocksPerSet);
    hardReady.assign(size_t(s.sets) * groupCount, 0);
}

size_t TileCaster::fixedBytes(const LightSamples& samples) {
    size_t blocksPerSet = 0;
    for (const LightSampleGroup& g : samples.groups) blocksPerSet += hardShadowBlocksFor(g.count);
    const size_t groups = size_t(samples.groupCount()), sets = size_t(samples.sets);
    return sets * blocksPerSet * sizeof(HardShadowBlock) + groups * sizeof(PenumbraVolume) + sets * groups * sizeof(uint32_t) +
           MaskPool::slackBytes(int(groups));
}

void TileCaster::build(std::vector<ReceiverInput> inputs) {
    {
        ScopedTimer timer(stats_.buildSeconds);
        hierarchy_.build(std::move(inputs));
    }
    if (!options.lazyMasks)
        for (auto& m : hierarchy_.mask) m = pool_.allocate();
    notePeaks();
}

void TileCaster::notePeaks() {
    stats_.peakHierarchyBytes = std::max(stats_.peakHierarchyBytes, hierarchy_.hierarchyBytes());
    stats_.peakReceiverBytes = std::max(stats_.peakReceiverBytes, hierarchy_.receiverBytes());
}

void TileCaster::prepareTableBlocker() {
    tableBlocker = (*tables)[currentLight].prepare(*tri);
    if (tableBlocker.split) sideCache.reset(samples.sets), tableBlocker.sideCache = &sideCache;
}

void TileCaster::buildGroupVolumes() {
    for (uint32_t k = samples.lightFirstGroup[currentLight]; k < samples.lightFirstGroup[currentLight + 1]; ++k)
        buildPenumbraVolume(samples.groups[k].bound, *tri, groupVolumes[k], nullptr, kernels.level);
    groupVolumesBuilt = true;
}

// The two helpers of castReceiver() are inlined into it, as when they were one function: out of
// line they cost a few percent of the cast (perf, grids under the 4x light).
[[gnu::always_inline]] inline const HardShadowBlock* TileCaster::hardShadowBlocks(uint32_t set, uint32_t k, uint64_t needed,
                                                                                 uint32_t& which) {
    const size_t slot = size_t(set) * groupCount + k;
    const LightSampleGroup& g = samples.groups[k];
    HardShadowBlock* blocks = &hardBlocks[set * blocksPerSet + blockFirst[k]];
    which = blocksHolding(needed);
    uint32_t missing = which & ~hardReady[slot];
    if (missing) {
        if (!hardReady[slot]) hardReadyList.push_back(uint32_t(slot));
        hardReady[slot] |= missing;
        const glm::vec3* first = &samples.position(int(set), int(g.first));
        for (; missing; missing &= missing - 1) {
            const int b = __builtin_ctz(missing), lane0 = b * HardShadowBlock::kLanes;
            kernels.build(blocks[b], first + lane0, std::min<int>(HardShadowBlock::kLanes, int(g.count) - lane0),
                          samples.w(g.light), *tri);
        }
    }
    return blocks;
}

bool TileCaster::inFrontOfClosed(const Box& box) const {
    // The corner nearest T's plane from the front, then a margin for the rounding of every
    // receiver's own distance (castReceiver skips a receiver when dist > eps(r)).
    const glm::dvec3& n = tri->plane.n;
    const glm::dvec3 c{n.x > 0 ? box.lo.x : box.hi.x, n.y > 0 ? box.lo.y : box.hi.y, n.z > 0 ? box.lo.z : box.hi.z};
    const glm::dvec3 d = glm::abs(c - tri->v[0]);
    return distanceBehind(*tri, c) > closedFrontMargin(options, largestCoordinate(box), d.x + d.y + d.z);
}

bool TileCaster::castTriangle(const BlockerTriangle& t, const PenumbraVolume* lightVolumes, const uint8_t* lightActive) {
    reachedRoot = false;
    ReceiverHierarchy& h = hierarchy_;
    if (h.nodes.empty()) return false;
    if (umbra() && options.rebuild && h.umbraCount > 0 &&
        double(h.umbraCount) > options.rebuildThreshold * double(h.liveCount())) {  // line 29
        {
            ScopedTimer timer(stats_.buildSeconds);
            h.rebuild();
        }
        ++stats_.rebuilds;
        notePeaks();
        if (h.nodes.empty()) return false;
    }
    if (umbra() && h.nodeFullUmbra[0]) return false;
    tri = &t;
    outline = kOutlineUnknown;
    for (uint32_t slot : hardReadyList) hardReady[slot] = 0;
    hardReadyList.clear();
    for (currentLight = 0; currentLight < uint32_t(samples.lightCount()); ++currentLight) {
        if (!lightActive[currentLight]) continue;
        lightVolume = &lightVolumes[currentLight];
        groupVolumesBuilt = false, leafReceivers = 0;
        uint32_t g0 = samples.lightFirstGroup[currentLight], g1 = samples.lightFirstGroup[currentLight + 1];
        if (!options.lazyVolumes) {  // optimization C off: build everything before traversal
            if (tables) prepareTableBlocker();
            buildGroupVolumes();
            uint32_t which;
            for (uint32_t set = 0; set < uint32_t(samples.sets); ++set)
                for (uint32_t k = g0; k < g1; ++k) hardShadowBlocks(set, k, samples.groups[k].fullMask(), which);
        }
        stack.clear();
        for (uint32_t k = g0; k < g1; ++k) stack.push_back({k, kAllPlanes});
        uint32_t planes = lightVolume->all();
        if (enters(0, planes)) visit(0, planes, 0, stack.size());
    }
    return reachedRoot;
}

[[gnu::always_inline]] inline bool TileCaster::enters(uint32_t nodeIndex, uint32_t& planes) {
    const ReceiverHierarchy& h = hierarchy_;
    ++stats_.visits;
    if (umbra() && h.nodeFullUmbra[nodeIndex]) return false;  // line 35
    const ReceiverHierarchy::Node& node = h.nodes[nodeIndex];
    uint32_t active = options.activePlanes ? planes : lightVolume->all();
    if (!boxTest(*lightVolume, Box{node.lo, node.hi}, active)) return false;  // line 36
    planes = options.activePlanes ? active : lightVolume->all();
    return true;
}

void TileCaster::visit(uint32_t nodeIndex, uint32_t planes, size_t groupsBegin, size_t groupsEnd) {
    ReceiverHierarchy& h = hierarchy_;
    // By reference: a copy went through the stack, and reading it back stalled on store forwarding
    // (16 % of visit()'s samples on FLOWERS). Nothing below changes the nodes; rebuilds happen
    // between triangles.
    const ReceiverHierarchy::Node& node = h.nodes[nodeIndex];
    const Box box{node.lo, node.hi};
    if (tri->closed && !lightVolume->frontCulled && inFrontOfClosed(box)) return;
    if (nodeIndex == 0) reachedRoot = true;

    const size_t begin = stack.size();
    if (stack.capacity() < begin + (groupsEnd - groupsBegin)) stack.reserve(2 * (begin + groupCount));
    const uint64_t* nodeBits = &h.nodeGroupUmbra[size_t(nodeIndex) * umbraWords];
    for (size_t i = groupsBegin; i < groupsEnd; ++i) {  // lines 38-45
        ActiveGroup g = stack[i];
        if (umbra() && h.groupUmbraBit(nodeBits, g.group)) continue;
        if (groupVolumesBuilt) {
            const PenumbraVolume& v = groupVolumes[g.group];
            uint32_t p = options.activePlanes ? (g.planes & v.all()) : v.all();
            if (!boxTest(v, box, p)) continue;
            stack.push_back({g.group, options.activePlanes ? p : kAllPlanes});
        } else {
            stack.push_back({g.group, kAllPlanes});
        }
    }
    const size_t end = stack.size();
    if (begin == end) return;  // line 46

    // A node's umbra bits are its children's AND, so they change only when a receiver's did below.
    const bool changedBefore = umbraChanged;
    umbraChanged = false;
    if (!node.leaf()) {
        // Both children's first tests here, before either descent: a child outside V_L (44 % of
        // the nodes tested on FLOWERS) then costs no call, and its box load overlaps the other's.
        // The descent into the first cannot change the second's umbra flag (disjoint receivers).
        uint32_t planesA = planes, planesB = planes;
        const bool a = enters(node.first, planesA), b = enters(node.first + 1, planesB);
        if (a) visit(node.first, planesA, begin, end);
        if (b) visit(node.first + 1, planesB, begin, end);
    } else {
        castLeaf(node.first, node.count, planes, begin, end);
    }
    if (umbra() && umbraChanged) h.foldUmbra(nodeIndex);  // lines 50-54, 77-80
    umbraChanged |= changedBefore;
    stack.resize(begin);
}

void TileCaster::castLeaf(uint32_t first, uint32_t count, uint32_t lightPlanes, size_t groupsBegin, size_t groupsEnd) {
    const ReceiverHierarchy& h = hierarchy_;
    for (uint32_t r0 = first; r0 < first + count; r0 += 4) {
        const int n = int(std::min<uint32_t>(4, first + count - r0));
        uint32_t live = (1u << n) - 1u;
        if (umbra())  // line 57
            for (int i = 0; i < n; ++i) live &= ~(uint32_t(h.fullUmbra[r0 + i]) << i);
        if (!live) continue;
        // Line 58, then two exact early-outs of the rule (LeafPrefilter.h): a receiver within its
        // epsilon of T's plane cannot be blocked by any sample (BlockingRule.h); a closed solid's
        // face blocks a receiver in front of it only for samples behind it. Such a segment leaves
        // the solid through T, so it entered it through a face that the sample sees, and that face
        // blocks it: Sintorn et al. 2008's one-side argument, per receiver instead of per
        // triangle, with the same exceptions as closed casters (docs/performance.md).
        double dist[4];
        if (kernels.level == SimdLevel::Avx2) {  // the kernels' level: same bits either way
            live &= leafPrefilterAvx2(*lightVolume, lightPlanes, *tri, &h.position[r0], &h.epsilon[r0], n, dist);
        } else {
            for (uint32_t rest = live; rest; rest &= rest - 1) {
                const int i = __builtin_ctz(rest);
                if (!passesLeafPrefilter(*lightVolume, lightPlanes, *tri, h.position[r0 + i], h.epsilon[r0 + i], dist[i]))
                    live &= ~(1u << i);
            }
        }
        if (!live) continue;
        if (!groupVolumesBuilt) {  // lines 60-64, for the first receiver reached
            if (tables && leafReceivers == 0) prepareTableBlocker();
            // A small blocker reaches a few receivers, and its table rows decide all their
            // groups at once; its V_Gk would cost more to build than their culling saves.
            leafReceivers += uint32_t(__builtin_popcount(live));
            if (!tables || tableBlocker.split || leafReceivers > options.groupVolumesAfter) buildGroupVolumes();
        }
        // With table rows (T's plane clear of the light), the look-ups of the chunk's receivers
        // first, each one's cells prefetched: a receiver's four cells are as many likely cache
        // misses (the table is a megabyte per sample set, and neighbours use different sets), and
        // the four receivers' misses now overlap (docs/performance.md, "Table cells prefetched").
        RowLookup looked[4];
        const bool rowsFirst = tables && !tableBlocker.split;
        if (rowsFirst) {
            const SampleMaskTable& table = (*tables)[currentLight];
            for (uint32_t rest = live; rest; rest &= rest - 1) {
                const int i = __builtin_ctz(rest);
                const uint32_t r = r0 + uint32_t(i);
                looked[i].result = table.lookup(tableBlocker, h.sampleSet[r], h.position[r], dist[i], h.epsilon[r], looked[i].rows);
                if (looked[i].result == SampleMaskTable::Lookup::Rows)
                    for (const uint64_t* cell : looked[i].rows.sure) __builtin_prefetch(cell);
            }
        }
        // A split blocker's footprints, four receivers at once: only their samples can be blocked.
        SampleMaskTable::FootprintResult footprintResult[4];
        SampleMaskTable::Footprint footprint[4];
        const bool footprints = tables && tableBlocker.split && options.footprints;
        if (footprints)
            (*tables)[currentLight].footprints(tableBlocker, &h.position[r0], &h.sampleSet[r0], dist, &h.epsilon[r0], live,
                                               footprintResult, footprint);
        for (; live; live &= live - 1) {
            const int i = __builtin_ctz(live);
            const SampleMaskTable::Footprint* inFootprint = nullptr;
            if (footprints) {
                if (footprintResult[i] == SampleMaskTable::FootprintResult::NoneBlocked) continue;
                if (footprintResult[i] == SampleMaskTable::FootprintResult::Box) inFootprint = &footprint[i];
            }
            castReceiver(r0 + uint32_t(i), dist[i], groupsBegin, groupsEnd, rowsFirst ? &looked[i] : nullptr, inFootprint);
        }
    }
}

void TileCaster::castReceiver(uint32_t r, double dist, size_t groupsBegin, size_t groupsEnd, const RowLookup* looked,
                              const SampleMaskTable::Footprint* inFootprint) {
    ReceiverHierarchy& h = hierarchy_;
    const glm::dvec3& p = h.position[r];
    const double eps = h.epsilon[r];

    const uint32_t set = h.sampleSet[r];
    const SampleMaskTable* table = tables ? &(*tables)[currentLight] : nullptr;
    uint64_t* bits = &h.groupUmbra[size_t(r) * umbraWords];
    uint64_t* mask = h.mask[r] != MaskPool::kNone ? pool_.data(h.mask[r]) : nullptr;
    // A blocker whose plane cuts the light reaches far more receivers than it shadows, and its
    // table look-up takes four lines: V_Gk's point test first rejects most receivers more
    // cheaply, and the look-up is only worth it for enough open samples. Otherwise, with table
    // rows, the point test would only repeat what the rows decide.
    const bool pointTestFirst = !table || tableBlocker.split;
    const uint32_t openBits = gatherCandidates(r, p, pointTestFirst, inFootprint, groupsBegin, groupsEnd);
    if (candidates.empty()) return;
    SampleMaskTable::Rows rows;
    auto lookup = SampleMaskTable::Lookup::Exact;
    if (looked) {
        lookup = looked->result, rows = looked->rows;
        if (lookup == SampleMaskTable::Lookup::NoneBlocked) return;
    } else if (table && (!tableBlocker.split || openBits >= kSplitTableMinimumBits)) {
        lookup = table->lookup(tableBlocker, set, p, dist, eps, rows);
        if (lookup == SampleMaskTable::Lookup::NoneBlocked) return;  // no bit has changed yet
    }
    // Without rows (the table gave up on this receiver), the groups' point tests need V_Gk.
    if (!groupVolumesBuilt && lookup != SampleMaskTable::Lookup::Rows) buildGroupVolumes();
    bool haveOffsets = false;
    EdgeOffsets offsets;  // r - v_e for the exact tests and the alpha test, once per receiver
    auto edgeOffsets = [&]() -> const EdgeOffsets& {
        if (!haveOffsets) offsets = EdgeOffsets(*tri, p), haveOffsets = true;
        return offsets;
    };
    for (const ActiveGroup& g : candidates) {
        const LightSampleGroup& group = samples.groups[g.group];
        const uint64_t before = mask ? mask[g.group] : 0;
        uint64_t word = before, open = ~word & group.fullMask(), alphaSure = 0;
        if (inFootprint) open &= inFootprint->word(g.group - table->firstGroup());
        const PenumbraVolume& v = groupVolumes[g.group];
        if (!pointTestFirst && lookup != SampleMaskTable::Lookup::Rows && !contains(v, p, g.planes & v.all())) continue;
        if (lookup == SampleMaskTable::Lookup::Rows) {  // sure bits are blocked; bits outside maybe are not
            const uint32_t k = g.group - table->firstGroup();
            uint64_t sure = rows.sureWord(k) & open, undecided = rows.maybeWord(k) & open & ~sure;
            stats_.tableDecided += uint64_t(__builtin_popcountll(open & ~undecided));
            // An alpha triangle blocks a sure bit (the rule blocks it) only where the alpha test
            // passes: it joins the kernels' hits for the test.
            if (tri->alpha) alphaSure = sure, sure = 0;
            word |= sure;
            open = undecided;
        }
        uint64_t hits = alphaSure;
        AlphaVerdict verdict = AlphaVerdict::Mixed;
        if (tri->alpha && options.alphaBounds && __builtin_popcountll(alphaSure | open) >= kAlphaBoundMinimumBits) {
            verdict = alphaOverBound(alphaTable, *tri, p, group.bound);
            ++stats_.alphaGroupTests;
            if (verdict != AlphaVerdict::Mixed) ++stats_.alphaGroupsDecided;
            if (verdict == AlphaVerdict::Clear) hits = open = 0;  // no hit of the group passes
        }
        if (open) {
            uint32_t which;
            const HardShadowBlock* hard = hardShadowBlocks(set, g.group, open, which);
            stats_.hardTests += uint64_t(__builtin_popcountll(open));
            hits |= kernels.test(hard, which, edgeOffsets(), dist, eps) & open;
        }
        if (tri->alpha && hits && verdict == AlphaVerdict::Mixed) hits = alphaFilter(set, g.group, hits, p, edgeOffsets());
        word |= hits;
        if (word != before) {
            if (!mask) {  // line 59, deferred until a bit is really set
                h.mask[r] = pool_.allocate();
                mask = pool_.data(h.mask[r]);
            }
            mask[g.group] = word;
        }
        if (umbra() && word == group.fullMask()) bits[g.group >> 6] |= 1ull << (g.group & 63), umbraChanged = true;
    }
    if (umbra() && fullWords(bits)) {  // lines 74-75
        h.fullUmbra[r] = 1;
        ++h.umbraCount;
        if (options.lazyMasks && mask) {
            pool_.release(h.mask[r]);
            h.mask[r] = MaskPool::kNone;
        }
    }
}
// Cold: kept out of the hot code's way, so that what the alpha test grows to (max_distance,
// textures) leaves the layout of castReceiver's loops alone (measured: moving them cost GRIDS 2 %).
[[gnu::cold]] uint64_t TileCaster::alphaFilter(uint32_t set, uint32_t k, uint64_t hits, const glm::dvec3& p,
                                               const EdgeOffsets& at) {
    // The hits' edge values from their hard-shadow blocks (built here for the table's sure bits):
    // the kernels' normals are the rule's cross products, so these are the values the reference
    // tests, without rebuilding each sample's volume (docs/performance.md, "Alpha tests").
    uint32_t which;
    const HardShadowBlock* blocks = hardShadowBlocks(set, k, hits, which);
    if (outline == kOutlineUnknown)
        outline = kernels.level == SimdLevel::Avx2 && alphaTable.outlineOf(tri->alpha, outlineOfTri) ? kOutlineYes : kOutlineNo;
    if (outline == kOutlineYes) {  // an analytic outline: four lanes at once, the same bits (OutlineTest.h)
        uint64_t kept = 0;
        for (uint32_t rest = which; rest; rest &= rest - 1) {
            const int b = __builtin_ctz(rest);
            const uint32_t lanes = uint32_t(hits >> (4 * b)) & 0xFu;
            if (!lanes) continue;
            kept |= uint64_t(outlineLanesAvx2(blocks[b], lanes, at, outlineOfTri)) << (4 * b);
        }
        stats_.alphaTests += uint64_t(__builtin_popcountll(hits));
        stats_.alphaRejected += uint64_t(__builtin_popcountll(hits & ~kept));
        return kept;
    }
    uint64_t kept = hits;
    for (uint64_t rest = hits; rest; rest &= rest - 1) {
        const int j = __builtin_ctzll(rest), lane = j % HardShadowBlock::kLanes;
        const HardShadowBlock& h = blocks[j / HardShadowBlock::kLanes];
        const double e[3] = {laneEdgeValue(h, 0, lane, at), laneEdgeValue(h, 1, lane, at), laneEdgeValue(h, 2, lane, at)};
        ++stats_.alphaTests;
        if (!alphaAtEdges(alphaTable, *tri, p, e).opaque) kept &= ~(1ull << j), ++stats_.alphaRejected;
    }
    return kept;
}

[[gnu::always_inline]] inline uint32_t TileCaster::gatherCandidates(uint32_t r, const glm::dvec3& p, bool pointTest,
                                                                   const SampleMaskTable::Footprint* footprint, size_t groupsBegin,
                                                                   size_t groupsEnd) {
    const ReceiverHierarchy& h = hierarchy_;
    const uint64_t* bits = &h.groupUmbra[size_t(r) * umbraWords];
    const uint64_t* mask = h.mask[r] != MaskPool::kNone ? pool_.data(h.mask[r]) : nullptr;
    candidates.clear();
    uint32_t openBits = 0;
    for (size_t i = groupsBegin; i < groupsEnd; ++i) {  // lines 65-73
        const ActiveGroup g = stack[i];
        if (umbra() && h.groupUmbraBit(bits, g.group)) continue;
        uint64_t open = ~(mask ? mask[g.group] : 0) & samples.groups[g.group].fullMask();
        if (footprint) open &= footprint->word(g.group - (*tables)[currentLight].firstGroup());
        if (!open) continue;
        const PenumbraVolume& v = groupVolumes[g.group];
        if (pointTest && !contains(v, p, g.planes & v.all())) continue;
        candidates.push_back(g);
        openBits += uint32_t(__builtin_popcountll(open));
    }
    return openBits;
}

}  // namespace penumbra
