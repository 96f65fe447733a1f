#include "bake/PenumbraCaster.h"

#include "bake/BlockingRule.h"
#include "bake/HardShadowBlock.h"
#include "bake/PenumbraVolume.h"
#include "bake/SampleMaskTable.h"
#include "receivers/MaskPool.h"
#include "receivers/ReceiverHierarchy.h"
#include "stream/TriangleSource.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <numeric>
#include <thread>

namespace penumbra {
namespace {

double secondsSince(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

constexpr uint32_t kAllPlanes = ~0u;  // "ALL": masked by the volume's own plane count when used

/// Every vertex of the light's bound strictly behind T's plane, beyond roundoff of the plane's
/// evaluation (unit normal, anchored at T, so a margin relative to the quantities suffices). For a
/// sun, every direction of the cone points away from T's front side.
bool facesAway(const BlockerTriangle& t, const ConvexBound& bound) {
    const glm::dvec3& v0 = t.v[0];
    for (const glm::dvec3& v : bound.vertices) {
        const glm::dvec3 d = v - bound.w * v0;
        const double m = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
        if (!(glm::dot(t.plane.n, d) < -1e-9 * m)) return false;
    }
    return !bound.vertices.empty();
}

/// The box around the receivers and the light's bound. A sun's rays leave the receivers towards
/// infinity: along every axis on which some direction of the bound has a positive (negative)
/// component, the box is unbounded above (below).
Box reachBox(const Box& receivers, const ConvexBound& bound) {
    Box reach = receivers;
    for (const glm::dvec3& v : bound.vertices) {
        if (!bound.directional()) {
            reach.lo = glm::min(reach.lo, roundToFloat(v, true)), reach.hi = glm::max(reach.hi, roundToFloat(v, false));
            continue;
        }
        for (int a = 0; a < 3; ++a) {
            if (v[a] > 0.0) reach.hi[a] = INFINITY;
            if (v[a] < 0.0) reach.lo[a] = -INFINITY;
        }
    }
    return reach;
}

struct ActiveGroup {
    uint32_t group;
    uint32_t planes;
};

}  // namespace

/// One tile: a hierarchy, a mask pool, and the per-triangle scratch of the traversal.
struct PenumbraCaster::Tile {
    const LightSamples& samples;
    const CastOptions& options;
    const std::vector<SampleMaskTable>* tables;  // per light, or nullptr when the option is off
    ReceiverHierarchy hierarchy;
    MaskPool pool;
    int groupCount, umbraWords;
    std::vector<uint64_t> allGroupsBits;  // umbra words with every group's bit set

    // Per-triangle state (Figure 3's "volumes-computed", split per light and per (set, group)).
    const BlockerTriangle* tri = nullptr;
    const PenumbraVolume* lightVolume = nullptr;
    bool groupVolumesBuilt = false;
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
    SampleMaskTable::Blocker tableBlocker;  // the current triangle against the current light
    bool reachedRoot = false;

    double buildSeconds = 0;
    uint64_t rebuilds = 0, hardTests = 0, tableDecided = 0;
    size_t peakHierarchyBytes = 0, peakReceiverBytes = 0;

    Tile(const LightSamples& s, const CastOptions& o, const std::vector<SampleMaskTable>* t)
        : samples(s), options(o), tables(t), hierarchy(o.hierarchy, s.groupCount()), pool(s.groupCount()),
          groupCount(s.groupCount()), umbraWords((s.groupCount() + 63) / 64), kernels(hardShadowKernels(o.simd)) {
        allGroupsBits.assign(umbraWords, 0);
        for (int k = 0; k < groupCount; ++k) allGroupsBits[k >> 6] |= 1ull << (k & 63);
        groupVolumes.resize(groupCount);
        for (const LightSampleGroup& g : s.groups) {
            blockFirst.push_back(uint32_t(blocksPerSet));
            blocksPerSet += (g.count + HardShadowBlock::kLanes - 1) / HardShadowBlock::kLanes;
        }
        hardBlocks.resize(size_t(s.sets) * blocksPerSet);
        hardReady.assign(size_t(s.sets) * groupCount, 0);
    }

    void build(std::vector<ReceiverInput> inputs) {
        auto t0 = std::chrono::steady_clock::now();
        hierarchy.build(std::move(inputs));
        buildSeconds += secondsSince(t0);
        if (!options.lazyMasks)
            for (auto& m : hierarchy.mask) m = pool.allocate();
        notePeaks();
    }

    void notePeaks() {
        peakHierarchyBytes = std::max(peakHierarchyBytes, hierarchy.hierarchyBytes());
        peakReceiverBytes = std::max(peakReceiverBytes, hierarchy.receiverBytes());
    }

    bool umbra() const { return options.umbraBits; }

    /// The per-triangle state that only a reached receiver needs: V_Gk and the table's blocker
    /// coefficients. Most blockers never reach a receiver of a given tile.
    void buildGroupVolumes() {
        for (uint32_t k = samples.lightFirstGroup[currentLight]; k < samples.lightFirstGroup[currentLight + 1]; ++k)
            buildPenumbraVolume(samples.groups[k].bound, *tri, groupVolumes[k]);
        if (tables) tableBlocker = (*tables)[currentLight].prepare(*tri);
        groupVolumesBuilt = true;
    }

    /// The hard-shadow blocks of group @p k in sample set @p set, with every block that holds a
    /// sample of @p needed built. Per-block laziness matters for small blockers, which touch a
    /// few receivers (so a few sets) and a few samples of each group.
    /// @return the group's first block and, in @p which, the blocks holding samples of @p needed.
    const HardShadowBlock* hardShadowBlocks(uint32_t set, uint32_t k, uint64_t needed, uint32_t& which) {
        const size_t slot = size_t(set) * groupCount + k;
        const LightSampleGroup& g = samples.groups[k];
        HardShadowBlock* blocks = &hardBlocks[set * blocksPerSet + blockFirst[k]];
        which = 0;
        for (uint64_t rest = needed; rest;) {
            const int b = __builtin_ctzll(rest) / HardShadowBlock::kLanes;
            which |= 1u << b;
            rest &= ~(0xFull << (HardShadowBlock::kLanes * b));
        }
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

    /// Processes one blocker against this tile; returns whether any root box met V_L.
    void castTriangle(const BlockerTriangle& t, const PenumbraVolume* lightVolumes, const uint8_t* lightActive) {
        reachedRoot = false;
        ReceiverHierarchy& h = hierarchy;
        if (h.nodes.empty()) return;
        if (umbra() && options.rebuild && h.umbraCount > 0 &&
            double(h.umbraCount) > options.rebuildThreshold * double(h.liveCount())) {  // line 29
            auto t0 = std::chrono::steady_clock::now();
            h.rebuild();
            buildSeconds += secondsSince(t0);
            ++rebuilds;
            notePeaks();
            if (h.nodes.empty()) return;
        }
        if (umbra() && h.nodeFullUmbra[0]) return;
        tri = &t;
        for (uint32_t slot : hardReadyList) hardReady[slot] = 0;
        hardReadyList.clear();
        for (currentLight = 0; currentLight < uint32_t(samples.lightCount()); ++currentLight) {
            if (!lightActive[currentLight]) continue;
            lightVolume = &lightVolumes[currentLight];
            groupVolumesBuilt = false;
            uint32_t g0 = samples.lightFirstGroup[currentLight], g1 = samples.lightFirstGroup[currentLight + 1];
            if (!options.lazyVolumes) {  // optimization C off: build everything before traversal
                buildGroupVolumes();
                uint32_t which;
                for (uint32_t set = 0; set < uint32_t(samples.sets); ++set)
                    for (uint32_t k = g0; k < g1; ++k) hardShadowBlocks(set, k, samples.groups[k].fullMask(), which);
            }
            stack.clear();
            for (uint32_t k = g0; k < g1; ++k) stack.push_back({k, kAllPlanes});
            visit(0, lightVolume->all(), 0, stack.size());
        }
    }

    void visit(uint32_t nodeIndex, uint32_t lightPlanes, size_t groupsBegin, size_t groupsEnd) {
        ReceiverHierarchy& h = hierarchy;
        const ReceiverHierarchy::Node node = h.nodes[nodeIndex];
        if (umbra() && h.nodeFullUmbra[nodeIndex]) return;  // line 35
        Box box{node.lo, node.hi};
        uint32_t planes = options.activePlanes ? lightPlanes : lightVolume->all();
        if (!intersects(*lightVolume, box, planes)) return;  // line 36
        if (!options.activePlanes) planes = lightVolume->all();
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
                if (!intersects(v, box, p)) continue;
                stack.push_back({g.group, options.activePlanes ? p : kAllPlanes});
            } else {
                stack.push_back({g.group, kAllPlanes});
            }
        }
        const size_t end = stack.size();
        if (begin == end) return;  // line 46

        if (!node.leaf()) {
            visit(node.first, planes, begin, end);
            visit(node.first + 1, planes, begin, end);
            if (umbra()) {  // lines 50-54
                h.nodeFullUmbra[nodeIndex] = h.nodeFullUmbra[node.first] & h.nodeFullUmbra[node.first + 1];
                uint64_t* bits = &h.nodeGroupUmbra[size_t(nodeIndex) * umbraWords];
                for (int w = 0; w < umbraWords; ++w)
                    bits[w] = h.nodeGroupUmbra[size_t(node.first) * umbraWords + w] &
                              h.nodeGroupUmbra[size_t(node.first + 1) * umbraWords + w];
            }
        } else {
            for (uint32_t r = node.first; r < node.first + node.count; ++r) castReceiver(r, planes, begin, end);
            if (umbra()) updateLeafBits(nodeIndex, node);
        }
        stack.resize(begin);
    }

    void castReceiver(uint32_t r, uint32_t lightPlanes, size_t groupsBegin, size_t groupsEnd) {
        ReceiverHierarchy& h = hierarchy;
        if (umbra() && h.fullUmbra[r]) return;  // line 57
        const glm::dvec3& p = h.position[r];
        if (!contains(*lightVolume, p, lightPlanes)) return;  // line 58
        // Cheap exact early-out: a receiver not behind T's plane (beyond epsilon) on either side
        // cannot be blocked by any sample (BlockingRule.h).
        const double dist = distanceBehind(*tri, p), eps = h.epsilon[r];
        if (!(dist > eps) && !(-dist > eps)) return;
        if (!groupVolumesBuilt) buildGroupVolumes();  // lines 60-64

        const uint32_t set = h.sampleSet[r];
        const SampleMaskTable* table = tables ? &(*tables)[currentLight] : nullptr;
        SampleMaskTable::Rows rows;  // sample mask table: looked up when a group first needs it
        auto lookup = SampleMaskTable::Lookup::Exact;
        bool lookedUp = !table;
        bool haveOffsets = false;
        EdgeOffsets offsets;  // r - v_e for the exact tests, once per receiver
        uint64_t* bits = &h.groupUmbra[size_t(r) * umbraWords];
        uint64_t* mask = h.mask[r] != MaskPool::kNone ? pool.data(h.mask[r]) : nullptr;
        for (size_t i = groupsBegin; i < groupsEnd; ++i) {  // lines 65-73
            const ActiveGroup g = stack[i];
            if (umbra() && h.groupUmbraBit(bits, g.group)) continue;
            const LightSampleGroup& group = samples.groups[g.group];
            const uint64_t before = mask ? mask[g.group] : 0;
            uint64_t word = before;
            uint64_t open = ~word & group.fullMask();
            if (!open) continue;
            if (!lookedUp) {
                lookedUp = true;
                lookup = table->lookup(tableBlocker, set, p, dist, eps, rows);
                if (lookup == SampleMaskTable::Lookup::NoneBlocked) return;  // no bit has changed yet
            }
            // With table rows, V_Gk's point test would only repeat what the rows decide.
            const PenumbraVolume& v = groupVolumes[g.group];
            if (lookup != SampleMaskTable::Lookup::Rows && !contains(v, p, g.planes & v.all())) continue;
            if (lookup == SampleMaskTable::Lookup::Rows) {  // sure bits are blocked; bits outside maybe are not
                const uint32_t k = g.group - table->firstGroup();
                const uint64_t sure = rows.sureWord(k) & open, undecided = rows.maybeWord(k) & open & ~sure;
                tableDecided += uint64_t(__builtin_popcountll(open & ~undecided));
                word |= sure;
                open = undecided;
            }
            if (open) {
                uint32_t which;
                const HardShadowBlock* hard = hardShadowBlocks(set, g.group, open, which);
                hardTests += uint64_t(__builtin_popcountll(open));
                if (!haveOffsets) offsets = EdgeOffsets(*tri, p), haveOffsets = true;
                word |= kernels.test(hard, which, offsets, dist, eps) & open;
            }
            if (word != before) {
                if (!mask) {  // line 59, deferred until a bit is really set
                    h.mask[r] = pool.allocate();
                    mask = pool.data(h.mask[r]);
                }
                mask[g.group] = word;
            }
            if (umbra() && word == group.fullMask()) bits[g.group >> 6] |= 1ull << (g.group & 63);
        }
        if (umbra() && std::equal(bits, bits + umbraWords, allGroupsBits.begin())) {  // lines 74-75
            h.fullUmbra[r] = 1;
            ++h.umbraCount;
            if (options.lazyMasks && mask) {
                pool.release(h.mask[r]);
                h.mask[r] = MaskPool::kNone;
            }
        }
    }

    void updateLeafBits(uint32_t nodeIndex, const ReceiverHierarchy::Node& node) {  // lines 77-80
        ReceiverHierarchy& h = hierarchy;
        uint64_t* bits = &h.nodeGroupUmbra[size_t(nodeIndex) * umbraWords];
        uint8_t full = 1;
        std::fill_n(bits, umbraWords, ~0ull);
        for (uint32_t r = node.first; r < node.first + node.count; ++r) {
            full &= h.fullUmbra[r];
            for (int w = 0; w < umbraWords; ++w) bits[w] &= h.groupUmbra[size_t(r) * umbraWords + w];
        }
        h.nodeFullUmbra[nodeIndex] = full;
    }
};

std::vector<std::vector<uint32_t>> partitionReceivers(const ReceiverSet& receivers, std::span<const uint32_t> ids,
                                                      int count) {
    std::vector<uint32_t> order(ids.begin(), ids.end());
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
        glm::vec3 e = hi - lo;
        int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
        int left = pieces / 2;
        size_t mid = begin + (end - begin) * left / pieces;
        std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end, [&](uint32_t a, uint32_t b) {
            float pa = receivers.position[a][axis], pb = receivers.position[b][axis];
            return pa < pb || (pa == pb && a < b);
        });
        self(self, begin, mid, left);
        self(self, mid, end, pieces - left);
    };
    split(split, 0, order.size(), std::max(1, count));
    return parts;
}

PenumbraCaster::PenumbraCaster(const LightSamples& samples, const ReceiverSet& receivers,
                               std::span<const uint32_t> sampleSetOf, const CastOptions& options, int tiles,
                               std::span<const uint32_t> receiverIds)
    : samples_(samples), options_(options) {
    std::vector<uint32_t> all;
    if (receiverIds.empty()) {
        all.resize(receivers.size());
        std::iota(all.begin(), all.end(), 0u);
        receiverIds = all;
    }
    if (options_.sampleTable)
        for (uint32_t l = 0; l < uint32_t(samples_.lightCount()); ++l)
            tables_.emplace_back(samples_, l, options_.sampleTableAngles, options_.sampleTableOffsets);
    auto parts = partitionReceivers(receivers, receiverIds, std::max(1, tiles));
    tiles_.resize(parts.size());
    tbb::parallel_for(size_t(0), parts.size(), [&](size_t t) {
        tiles_[t] = std::make_unique<Tile>(samples_, options_, options_.sampleTable ? &tables_ : nullptr);
        std::vector<ReceiverInput> inputs;
        inputs.reserve(parts[t].size());
        for (uint32_t id : parts[t]) {
            glm::dvec3 p(receivers.position[id]);
            inputs.push_back({p, receiverEpsilonOf(options_).at(p), id, sampleSetOf[id]});
        }
        tiles_[t]->build(std::move(inputs));
    });
    // Rebuilds only drop receivers, so boxes from the first build stay conservative.
    receiversBox_ = Box{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
    for (const auto& tile : tiles_)
        if (!tile->hierarchy.nodes.empty()) {
            receiversBox_.lo = glm::min(receiversBox_.lo, tile->hierarchy.nodes[0].lo);
            receiversBox_.hi = glm::max(receiversBox_.hi, tile->hierarchy.nodes[0].hi);
        }
    const glm::dvec3 lo(receiversBox_.lo), hi(receiversBox_.hi);
    const glm::dvec3 corners[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {lo.x, hi.y, lo.z}, {hi.x, hi.y, lo.z},
                                   {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {lo.x, hi.y, hi.z}, {hi.x, hi.y, hi.z}};
    for (const ConvexBound& bound : samples_.lightBounds) {
        reach_.push_back(reachBox(receiversBox_, bound));
        if (bound.directional()) reachHull_.emplace_back(boundingCone(bound.vertices), boundingBall(corners));
        else reachHull_.emplace_back(boundingBall(bound.vertices), boundingBall(corners));
    }
    // With several tiles, one can fall ringChunks() - 1 chunks behind the fastest before the
    // caller stops preparing and helps.
    ring_.resize(ringChunks(tiles_.size()));
    for (auto& b : ring_) b = std::make_unique<Batch>();
    tileNext_.assign(tiles_.size(), 0);
    tileBusy_ = std::make_unique<std::atomic<bool>[]>(tiles_.size());
    for (size_t t = 0; t < tiles_.size(); ++t) tileBusy_[t] = false;
}

PenumbraCaster::~PenumbraCaster() {
    // Only after an exception can tasks still be pending; they must not outlive the tiles.
    group_.cancel();
    try {
        group_.wait();
    } catch (...) {
    }
}

void PenumbraCaster::prepare(Batch& batch, std::span<const Triangle> blockers) {
    const size_t n = blockers.size(), lights = size_t(samples_.lightCount());
    batch.n = n;
    if (batch.prepared.size() < n) {
        batch.prepared.resize(n);
        batch.lightVolumes.resize(n * lights);
        batch.lightActive.resize(n * lights);
    }
    std::atomic<uint64_t> closedBackFaces{0};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 256), [&](const tbb::blocked_range<size_t>& range) {
        uint64_t backFaces = 0;
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const Triangle& tri = blockers[i];
            Box box{glm::min(glm::min(tri.v[0], tri.v[1]), tri.v[2]), glm::max(glm::max(tri.v[0], tri.v[1]), tri.v[2])};
            uint8_t* active = &batch.lightActive[i * lights];
            // Switches off the lights for which @p drop(l) holds; false when none is left.
            auto keepLights = [&](auto&& drop) {
                bool any = false;
                for (size_t l = 0; l < lights; ++l) {
                    if (active[l] && drop(l)) active[l] = 0;
                    any = any || active[l];
                }
                return any;
            };
            BlockerTriangle& prepared = batch.prepared[i];
            bool any = false;
            for (size_t l = 0; l < lights; ++l) {
                const Box& r = reach_[l];
                bool overlaps = box.lo.x <= r.hi.x && box.hi.x >= r.lo.x && box.lo.y <= r.hi.y && box.hi.y >= r.lo.y &&
                                box.lo.z <= r.hi.z && box.hi.z >= r.lo.z;
                active[l] = overlaps;
                any = any || overlaps;
            }
            prepared.valid = false;
            if (!any) continue;  // outside every light's reach: no penumbra volume needed
            // Beside the light: T's ball misses the hull of the light's and the receivers' balls.
            const glm::dvec3 v[3] = {glm::dvec3(tri.v[0]), glm::dvec3(tri.v[1]), glm::dvec3(tri.v[2])};
            const Ball ball = boundingBall(v);
            if (!keepLights([&](size_t l) { return reachHull_[l].misses(ball); })) continue;
            prepared = BlockerTriangle::from(tri);
            if (!prepared.valid) continue;
            // A closed surface's triangle with every light vertex strictly behind it: a segment
            // through it enters the solid, and the triangle where it leaves faces the light.
            if (options_.closedCasters && (tri.flags & kTriangleClosed) &&
                !keepLights([&](size_t l) { return facesAway(prepared, samples_.lightBounds[l]); })) {
                prepared.valid = false;
                ++backFaces;
                continue;
            }
            // V_L is built plane by plane and abandoned as soon as one plane leaves every receiver
            // outside (first the cap: every receiver on the light's side of T's plane), so a
            // blocker culled at the root rarely pays for its whole volume.
            if (!keepLights([&](size_t l) {
                    return !buildPenumbraVolume(samples_.lightBounds[l], prepared, batch.lightVolumes[i * lights + l],
                                                &receiversBox_);
                }))
                prepared.valid = false;
        }
        closedBackFaces += backFaces;
    });
    stats_.closedBackFaces += closedBackFaces;
}

void PenumbraCaster::castOnTile(size_t t, Batch& batch) {
    const size_t n = batch.n, lights = size_t(samples_.lightCount());
    Tile& tile = *tiles_[t];
    uint8_t* reached = &batch.reached[t * n];
    for (size_t i = 0; i < n; ++i) {
        reached[i] = 0;
        if (!batch.prepared[i].valid) continue;
        tile.castTriangle(batch.prepared[i], &batch.lightVolumes[i * lights], &batch.lightActive[i * lights]);
        reached[i] = tile.reachedRoot;
    }
    if (batch.remaining.fetch_sub(1) != 1) return;
    uint64_t culled = 0;  // the last tile: every tile's flags are written
    for (size_t i = 0; i < n; ++i) {
        bool any = false;
        for (size_t u = 0; u < tiles_.size() && !any; ++u) any = batch.reached[u * n + i];
        culled += !any;
    }
    culledAtRoot_ += culled;
}

void PenumbraCaster::drain(size_t t) {
    for (;;) {
        if (tileBusy_[t].exchange(true)) return;
        try {
            while (tileNext_[t] < published_.load()) {
                castOnTile(t, *ring_[tileNext_[t] % ring_.size()]);
                ++tileNext_[t];
            }
        } catch (...) {
            failed_ = true;  // the tile stays held: its state is unknown, nobody casts it again
            throw;
        }
        const uint64_t next = tileNext_[t];
        tileBusy_[t].store(false);
        // A chunk published after the loop's last check but before the release found the tile
        // busy; its task has returned, so this thread takes the chunk.
        if (next >= published_.load()) return;
    }
}

void PenumbraCaster::cast(std::span<const Triangle> blockers) {
    if (!started_) castStart_ = std::chrono::steady_clock::now(), started_ = true;
    const uint64_t c = published_.load();
    Batch& batch = *ring_[c % ring_.size()];
    // The slot still holds chunk c - ring size until every tile has cast it. Rather than wait,
    // this thread casts the tiles nobody holds; it yields only while the tiles that still need
    // the slot run on other threads.
    while (batch.remaining.load() > 0) {
        for (size_t t = 0; t < tiles_.size() && !failed_; ++t) drain(t);
        if (failed_) group_.wait();  // rethrows the tile's exception
        if (batch.remaining.load() > 0) std::this_thread::yield();
    }
    prepare(batch, blockers);
    batch.reached.resize(tiles_.size() * batch.n);
    batch.remaining.store(int(tiles_.size()));
    published_.store(c + 1);
    for (size_t t = 0; t < tiles_.size(); ++t) group_.run([this, t] { drain(t); });
    stats_.trianglesProcessed += blockers.size();
}

void PenumbraCaster::flush() {
    if (!started_) return;
    group_.wait();  // every publish ran drain() for every tile, so every tile is caught up
    started_ = false;
    // Wall time from the first chunk to the last tile: includes whatever the caller did between
    // chunks (reading the replay), which the tiles overlapped.
    stats_.castSeconds += secondsSince(castStart_);
    stats_.trianglesCulledAtRoot = culledAtRoot_.load();
}

void PenumbraCaster::finish(const MaskVisitor& visit) {
    flush();
    // Shading every receiver is a few percent of a bake; done on one thread it was most of the
    // time outside the cast. Receivers are independent, so visits run in parallel.
    tbb::parallel_for(size_t(0), tiles_.size(), [&](size_t t) {
        const Tile& tile = *tiles_[t];
        const ReceiverHierarchy& h = tile.hierarchy;
        tbb::parallel_for(tbb::blocked_range<size_t>(0, h.retired.size(), 1024), [&](const tbb::blocked_range<size_t>& range) {
            for (size_t i = range.begin(); i != range.end(); ++i) visit(h.retired[i], nullptr, true);
        });
        tbb::parallel_for(tbb::blocked_range<size_t>(0, h.liveCount(), 1024), [&](const tbb::blocked_range<size_t>& range) {
            for (size_t r = range.begin(); r != range.end(); ++r) {
                if (h.fullUmbra[r]) visit(h.id[r], nullptr, true);
                else visit(h.id[r], h.mask[r] != MaskPool::kNone ? tile.pool.data(h.mask[r]) : nullptr, false);
            }
        });
    });
}

size_t PenumbraCaster::preparedChunkBytes(size_t lights) {
    return kTriangleChunk * (sizeof(BlockerTriangle) + lights * (sizeof(PenumbraVolume) + 1));
}

CastStats PenumbraCaster::stats() const {
    CastStats s = stats_;
    for (const SampleMaskTable& table : tables_) s.sampleTableBytes += table.bytes();
    for (const auto& tile : tiles_) {
        s.hierarchyBuildSeconds += tile->buildSeconds;
        s.rebuilds += tile->rebuilds;
        s.peakLiveMasks += tile->pool.peakLive();
        s.peakMaskBytes += tile->pool.peakLive() * size_t(tile->pool.words()) * sizeof(uint64_t);
        s.peakHierarchyBytes += tile->peakHierarchyBytes;
        s.receiverBytes += tile->peakReceiverBytes;
        s.hardShadowTests += tile->hardTests;
        s.tableDecidedRelations += tile->tableDecided;
    }
    return s;
}

}  // namespace penumbra
