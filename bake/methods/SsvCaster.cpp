#include "bake/methods/SsvCaster.h"

#include "bake/methods/SsvKernels.h"
#include "bake/methods/SsvScene.h"
#include "bake/cast/SceneCaster.h"
#include "bake/rule/AlphaRule.h"
#include "stream/util/Progress.h"

#include <glm/geometric.hpp>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>

namespace penumbra {
namespace {

double maxAbs(const glm::dvec3& p) { return std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}); }

/// Collects ids without repeats: leaves list an item in every leaf its box overlaps. A stamp per
/// id (one query number) replaces sorting, which cost more than the rest of a frustum on GRIDS.
class IdSet {
public:
    void reset(size_t ids) { stamp_.assign(ids, 0), query_ = 0; }
    void begin(std::vector<uint32_t>& out) {
        out.clear(), out_ = &out;
        if (++query_ == 0) std::fill(stamp_.begin(), stamp_.end(), 0), query_ = 1;
    }
    void add(uint32_t id) {
        if (stamp_[id] != query_) stamp_[id] = query_, out_->push_back(id);
    }

private:
    std::vector<uint32_t> stamp_;
    uint32_t query_ = 0;
    std::vector<uint32_t>* out_ = nullptr;
};

using Term = SsvEdgeTerm;

inline double edgeValueAt(const Term& t, double lx, double ly, double lz) { return ssvEdgeValue(t, lx, ly, lz); }

inline double sideAt(const glm::dvec3& q, double x, double y, double z) { return q.x * x + q.y * y + q.z * z; }

/// What a group's bound says about a linear test of the samples: +1 when every sample is
/// robustly positive, -1 robustly negative, 0 undecided. The exact values at the bound's vertices
/// bound those of its hull; @p tol is far above the roundoff of any of them.
template <class F>
int robustSign(const ConvexBound& bound, double tol, F&& value) {
    int positive = 0, negative = 0;
    for (const glm::dvec3& v : bound.vertices) {
        const double x = value(v);
        positive += x > tol, negative += x < -tol;
    }
    const int n = int(bound.vertices.size());
    return positive == n ? 1 : (negative == n ? -1 : 0);
}

/// Relative tolerance of the group tests: 1e-9 of the size of the operands (sqrt(3) turns the
/// max-norm bounds below into Euclidean ones).
constexpr double kGroupTolerance = 1.8e-9;

/// Everything the per-receiver work shares.
struct Context {
    const LightSamples& samples;
    const SsvScene& scene;
    std::span<const uint32_t> sets;
    ReceiverEpsilon epsilon;
    SsvOptions options;
    const AlphaTable& alpha;
    std::vector<double> sx, sy, sz;           ///< every sample of every set, as the rule reads it
    std::vector<std::vector<uint32_t>> refs;  ///< [set * lights + light]: reference candidates
    std::vector<uint32_t> lightFirstSample;
    std::vector<double> groupMaxAbs;          ///< per group: largest |coordinate| of its bound's vertices
    double margin = 0;                        ///< box tests: roundoff far below it
};

/// Counters summed over one thread's receivers.
struct Local {
    uint64_t frustums = 0, edges = 0, silhouettes = 0, band = 0, straddlers = 0, refTriangles = 0, retries = 0,
             fallbacks = 0, alphaFaces = 0, alphaTests = 0;
};

/// One thread's scratch and the per-receiver algorithm.
class ReceiverCaster {
public:
    explicit ReceiverCaster(const Context& c) : c_(c) {
        size_t edges = 0;
        for (int li = 0; li < c.samples.lightCount(); ++li) edges = std::max(edges, c.scene.light(li).edges.size());
        edgeIds_.reset(edges), faceIds_.reset(c.scene.faces().size()), straddlerIds_.reset(c.scene.faces().size());
        alphaIds_.reset(c.scene.alphaFaces().size());
    }

    void cast(uint32_t receiver, const glm::dvec3& r, uint64_t* row, Local& local) {
        const int set = int(c_.sets[receiver]);
        for (int li = 0; li < c_.samples.lightCount(); ++li) castLight(li, set, r, row, local);
    }

private:
    void castLight(int li, int set, const glm::dvec3& r, uint64_t* row, Local& local);
    void conePlanes(const ConvexBound& bound, const glm::dvec3& r);
    bool chooseReference(int li, int set, const glm::dvec3& r, Local& local);
    void addTerm(uint32_t face, int e, const SsvLight& light);
    void integrate(const Term& t, int li, int set);
    void testStraddlers(int li, int set, const glm::dvec3& r);
    bool outsideAnEdge(const BlockerTriangle& t, double s, const ConvexBound& bound, double gMax) const;
    void castPerSample(int li, int set, const glm::dvec3& r);
    void testCutouts(int li, int set, const glm::dvec3& r, Local& local);
    bool active(uint32_t face, const SsvLight& light, const glm::dvec3& r) const {
        const int8_t side = light.side[face];
        return side != 0 && double(-side) * distanceBehind(c_.scene.faces()[face].t, r) > eps_;
    }
    glm::dvec3 sample(int set, uint32_t k) const {
        const size_t i = size_t(set) * c_.samples.sampleCount + k;
        return {c_.sx[i], c_.sy[i], c_.sz[i]};
    }

    const Context& c_;
    double w_ = 1, eps_ = 0;
    glm::dvec3 receiver_{0.0};
    glm::dvec3 ref_{0.0}, dref_{0.0};
    int depthRef_ = 0;
    std::vector<KdPlane> planes_;
    std::vector<uint32_t> edges_, straddlers_, faces_, cutouts_;
    IdSet edgeIds_, faceIds_, straddlerIds_, alphaIds_;
    std::vector<Term> terms_;
    std::vector<int> depth_;     ///< per sample of the light: depth complexity of A
    std::vector<uint8_t> blocked_;
    std::vector<double> dx_, dy_, dz_;  ///< per sample of the light: l - w r
};

void ReceiverCaster::conePlanes(const ConvexBound& bound, const glm::dvec3& r) {
    planes_.clear();
    for (const auto& [i, j] : bound.edges) {
        glm::dvec3 n = glm::cross(bound.vertices[i] - w_ * r, bound.vertices[j] - w_ * r);
        const double length = glm::length(n);
        if (!(length > 0) || !std::isfinite(length)) continue;
        n /= length;
        bool allIn = true, allOut = true;
        for (const glm::dvec3& v : bound.vertices) {
            const glm::dvec3 d = v - w_ * r;
            const double value = glm::dot(n, d), tol = 1e-9 * glm::length(d);
            allIn = allIn && value >= -tol, allOut = allOut && value <= tol;
        }
        if (allIn == allOut) continue;  // not a supporting plane (or a degenerate one)
        planes_.push_back({allIn ? n : -n, r, c_.margin});
    }
}

bool ReceiverCaster::chooseReference(int li, int set, const glm::dvec3& r, Local& local) {
    const SsvLight& light = c_.scene.light(li);
    for (uint32_t k : c_.refs[size_t(set) * c_.samples.lightCount() + li]) {
        const glm::dvec3 l = sample(set, k);
        const glm::dvec3 d = l - w_ * r;
        faceIds_.begin(faces_);
        light.tree.visitSegment(r, d, w_ == 0 ? INFINITY : 1.0, c_.margin, [&](uint32_t leaf) {
            for (uint32_t f : light.tree.items(leaf, kSsvTriangleItem)) faceIds_.add(f);
        });
        local.refTriangles += faces_.size();
        int depth = 0;
        bool fragile = false;
        for (uint32_t f : faces_) {
            const BlockerTriangle& t = c_.scene.faces()[f].t;
            if (!active(f, light, r)) continue;  // never blocks r, and its edges are never integrated
            const HardShadowVolume h = makeHardShadowVolume(l, w_, t);
            bool inside = true;
            for (int e = 0; e < 3; ++e) {
                const double value = edgeValue(h, t, e, r);
                const glm::dvec3 &a = t.v[e], &b = t.v[(e + 1) % 3];
                fragile = fragile || std::abs(value) <= 1e-9 * glm::length(l - w_ * a) * glm::length(b - a) * glm::length(r - a);
                inside = inside && value >= 0.0;
            }
            if (fragile) break;
            depth += inside;  // the rule's decision: active faces pass the band and side tests
        }
        if (fragile) {
            ++local.retries;
            continue;
        }
        ref_ = l, dref_ = d, depthRef_ = depth;
        return true;
    }
    return false;
}


void ReceiverCaster::addTerm(uint32_t face, int e, const SsvLight& light) {
    const BlockerTriangle& f = c_.scene.faces()[face].t;
    const glm::dvec3 &a = f.v[e], &b = f.v[(e + 1) % 3];
    Term t;
    t.wa = w_ * a, t.ba = b - a, t.ra = receiver_ - a;
    t.s = double(light.side[face]);
    t.qa = glm::cross(a - receiver_, dref_), t.qb = glm::cross(b - receiver_, dref_);
    t.refInside = edgeValueAt(t, ref_.x, ref_.y, ref_.z) >= 0.0;
    terms_.push_back(t);
}

void ReceiverCaster::integrate(const Term& t, int li, int set) {
    const LightSamples& s = c_.samples;
    const uint32_t firstSample = c_.lightFirstSample[size_t(li)];
    const double edgeScale = kGroupTolerance * glm::length(t.ba) * glm::length(t.ra), waMax = maxAbs(t.wa);
    const double qaScale = kGroupTolerance * glm::length(t.qa), qbScale = kGroupTolerance * glm::length(t.qb);
    const double wrMax = w_ * maxAbs(receiver_);
    const size_t base = size_t(set) * s.sampleCount;
    for (uint32_t k = s.lightFirstGroup[size_t(li)]; k < s.lightFirstGroup[size_t(li) + 1]; ++k) {
        const LightSampleGroup& g = s.groups[k];
        const double gMax = c_.groupMaxAbs[k];
        const int inside = robustSign(g.bound, edgeScale * (gMax + waMax),
                                      [&](const glm::dvec3& v) { return edgeValueAt(t, v.x, v.y, v.z); });
        if (inside != 0 && int(inside > 0) == t.refInside) continue;  // E keeps l0's sign on the whole group
        auto side = [&](const glm::dvec3& q, double scale) {
            return robustSign(g.bound, scale * (gMax + wrMax), [&](const glm::dvec3& v) {
                return sideAt(q, v.x - w_ * receiver_.x, v.y - w_ * receiver_.y, v.z - w_ * receiver_.z);
            });
        };
        const int sideA = side(t.qa, qaScale), sideB = side(t.qb, qbScale);
        if (sideA != 0 && sideA == sideB) continue;  // a and b on one side of every plane (r, l0, l)
        if (inside != 0 && sideA != 0 && sideB != 0) {  // every sample of the group crosses the edge face
            const int delta = int(inside > 0) - t.refInside;
            for (uint32_t j = 0; j < g.count; ++j) depth_[g.first + j - firstSample] += delta;
            continue;
        }
        const uint32_t local = g.first - firstSample;
        ssvIntegrateSamples(t, g.count, &c_.sx[base + g.first], &c_.sy[base + g.first], &c_.sz[base + g.first], &dx_[local],
                            &dy_[local], &dz_[local], &depth_[local]);
    }
}

/// True when every point of @p bound is robustly outside one of T's edges for the rule's sign
/// @p s: the edge value s det(l - w a, b - a, r - a) < 0 on the whole bound.
bool ReceiverCaster::outsideAnEdge(const BlockerTriangle& t, double s, const ConvexBound& bound, double gMax) const {
    for (int e = 0; e < 3; ++e) {
        Term term;
        term.wa = w_ * t.v[e], term.ba = t.v[(e + 1) % 3] - t.v[e], term.ra = receiver_ - t.v[e], term.s = s;
        const double tol = kGroupTolerance * glm::length(term.ba) * glm::length(term.ra) * (gMax + maxAbs(term.wa));
        if (robustSign(bound, tol, [&](const glm::dvec3& v) { return edgeValueAt(term, v.x, v.y, v.z); }) < 0) return true;
    }
    return false;
}

void ReceiverCaster::testStraddlers(int li, int set, const glm::dvec3& r) {
    const LightSamples& s = c_.samples;
    const uint32_t firstSample = c_.lightFirstSample[size_t(li)];
    for (uint32_t f : straddlers_) {
        const BlockerTriangle& t = c_.scene.faces()[f].t;
        const double dist = distanceBehind(t, r);
        // Only samples on the far side of T's plane from r can be blocked (the band test), so the
        // rule's s is -sign(dist) for every sample that matters, and a group robustly outside an
        // edge with that s is not blocked by T at all.
        if (!(std::abs(dist) > eps_)) continue;
        const double sFar = dist > 0 ? -1.0 : 1.0;
        for (uint32_t k = s.lightFirstGroup[size_t(li)]; k < s.lightFirstGroup[size_t(li) + 1]; ++k) {
            const LightSampleGroup& g = s.groups[k];
            if (outsideAnEdge(t, sFar, g.bound, c_.groupMaxAbs[k])) continue;
            const size_t i = size_t(set) * s.sampleCount + g.first;
            ssvStraddlerSamples(t, w_, r, dist, eps_, g.count, &c_.sx[i], &c_.sy[i], &c_.sz[i], &blocked_[g.first - firstSample]);
        }
    }
}

void ReceiverCaster::testCutouts(int li, int set, const glm::dvec3& r, Local& local) {
    if (c_.scene.alphaFaces().empty()) return;
    const LightSamples& s = c_.samples;
    const uint32_t firstSample = c_.lightFirstSample[size_t(li)];
    alphaIds_.begin(cutouts_);
    c_.scene.alphaTree().visitCone(planes_, [&](uint32_t leaf) {
        for (uint32_t f : c_.scene.alphaTree().items(leaf, kSsvTriangleItem)) alphaIds_.add(f);
    });
    local.alphaFaces += cutouts_.size();
    for (uint32_t f : cutouts_) {
        const BlockerTriangle& t = c_.scene.alphaFaces()[f];
        const double dist = distanceBehind(t, r);
        if (!(std::abs(dist) > eps_)) continue;  // within the band: the rule blocks nothing
        const double sFar = dist > 0 ? -1.0 : 1.0;  // as for straddlers: the only s that can block
        for (uint32_t k = s.lightFirstGroup[size_t(li)]; k < s.lightFirstGroup[size_t(li) + 1]; ++k) {
            const LightSampleGroup& g = s.groups[k];
            if (outsideAnEdge(t, sFar, g.bound, c_.groupMaxAbs[k])) continue;
            for (uint32_t j = 0; j < g.count; ++j) {
                uint8_t& blocked = blocked_[g.first + j - firstSample];
                if (blocked) continue;
                ++local.alphaTests;
                const HardShadowVolume h = makeHardShadowVolume(sample(set, g.first + j), w_, t);
                blocked = blocksWithAlpha(h, t, r, dist, eps_, c_.alpha);
            }
        }
    }
}

void ReceiverCaster::castPerSample(int li, int set, const glm::dvec3& r) {
    const SsvLight& light = c_.scene.light(li);
    faceIds_.begin(faces_);
    light.tree.visitCone(planes_, [&](uint32_t leaf) {
        for (int kind : {int(kSsvStraddlerItem), int(kSsvTriangleItem)})
            for (uint32_t f : light.tree.items(leaf, kind)) faceIds_.add(f);
    });
    const uint32_t first = c_.lightFirstSample[size_t(li)];
    for (size_t local = 0; local < blocked_.size(); ++local)
        for (uint32_t f : faces_)
            if (blocks(sample(set, uint32_t(first + local)), w_, r, c_.scene.faces()[f].t, c_.epsilon)) {
                blocked_[local] = 1;
                break;
            }
}

void ReceiverCaster::castLight(int li, int set, const glm::dvec3& r, uint64_t* row, Local& local) {
    const LightSamples& s = c_.samples;
    const SsvLight& light = c_.scene.light(li);
    w_ = s.w(uint32_t(li)), eps_ = c_.epsilon.at(r), receiver_ = r;
    const uint32_t first = c_.lightFirstSample[size_t(li)], count = c_.lightFirstSample[size_t(li) + 1] - first;
    blocked_.assign(count, 0);
    ++local.frustums;
    conePlanes(s.lightBounds[size_t(li)], r);

    if (!chooseReference(li, set, r, local)) {
        ++local.fallbacks;
        castPerSample(li, set, r);
    } else {
        // The potential silhouette edges and straddlers the frustum reaches.
        edgeIds_.begin(edges_), straddlerIds_.begin(straddlers_);
        light.tree.visitCone(planes_, [&](uint32_t leaf) {
            for (uint32_t e : light.tree.items(leaf, kSsvEdgeItem)) edgeIds_.add(e);
            for (uint32_t f : light.tree.items(leaf, kSsvStraddlerItem)) straddlerIds_.add(f);
        });
        terms_.clear();
        for (uint32_t id : edges_) {
            const SsvEdge& edge = light.edges[id];
            const SsvFace& f0 = c_.scene.faces()[edge.face[0]];
            const glm::dvec3 &a = f0.t.v[edge.edge[0]], &b = f0.t.v[(edge.edge[0] + 1) % 3];
            bool outside = false;
            for (const KdPlane& p : planes_)
                outside = outside || (glm::dot(p.n, a - r) < -p.margin && glm::dot(p.n, b - r) < -p.margin);
            if (outside) continue;
            ++local.edges;
            for (int j = 0; j < 2; ++j)
                if (edge.face[j] != kNoFace && active(edge.face[j], light, r)) addTerm(edge.face[j], edge.edge[j], light);
        }
        // Shared edges that are not potential silhouettes still bound A where r lies in the band
        // behind one face and the other blocks: found from the band triangles around r.
        const size_t before = terms_.size();
        faceIds_.begin(faces_);
        light.tree.visitPoint(r, c_.margin, [&](uint32_t leaf) {
            for (uint32_t f : light.tree.items(leaf, kSsvTriangleItem)) faceIds_.add(f);
        });
        for (uint32_t f : faces_) {
            const SsvFace& face = c_.scene.faces()[f];
            const double x = double(-light.side[f]) * distanceBehind(face.t, r);
            if (!(x > 0) || x > eps_) continue;  // not in the band behind the face
            for (int e = 0; e < 3; ++e) {
                const uint32_t g = face.neighbor[e];
                if ((light.potential[f] >> e & 1) || g == kNoFace || !active(g, light, r)) continue;
                addTerm(g, face.neighborEdge[e], light);
            }
        }
        local.band += terms_.size() - before;
        local.silhouettes += terms_.size();
        local.straddlers += straddlers_.size();

        depth_.assign(count, depthRef_);
        dx_.resize(count), dy_.resize(count), dz_.resize(count);
        for (uint32_t k = 0; k < count; ++k) {
            const glm::dvec3 d = sample(set, first + k) - w_ * r;
            dx_[k] = d.x, dy_[k] = d.y, dz_[k] = d.z;
        }
        for (const Term& t : terms_) integrate(t, li, set);
        for (uint32_t k = 0; k < count; ++k) blocked_[k] = depth_[k] > 0;
        testStraddlers(li, set, r);
    }
    testCutouts(li, set, r, local);
    for (uint32_t k = s.lightFirstGroup[size_t(li)]; k < s.lightFirstGroup[size_t(li) + 1]; ++k) {
        const LightSampleGroup& g = s.groups[k];
        uint64_t word = 0;
        for (uint32_t j = 0; j < g.count; ++j) word |= uint64_t(blocked_[g.first + j - first]) << j;
        row[k] = word;
    }
}

/// Reference candidates per set and light: the samples nearest the centre of the light's bound.
std::vector<std::vector<uint32_t>> referenceCandidates(const LightSamples& s, int count) {
    std::vector<std::vector<uint32_t>> out(size_t(s.sets) * s.lightCount());
    uint32_t first = 0;
    for (int li = 0; li < s.lightCount(); ++li) {
        const ConvexBound& bound = s.lightBounds[size_t(li)];
        glm::dvec3 centre(0.0);
        for (const glm::dvec3& v : bound.vertices) centre += v;
        centre /= double(std::max<size_t>(1, bound.vertices.size()));
        uint32_t end = first;
        while (end < uint32_t(s.sampleCount) && s.sampleLight[end] == uint32_t(li)) ++end;
        for (int set = 0; set < s.sets; ++set) {
            std::vector<uint32_t> order(end - first);
            for (uint32_t k = first; k < end; ++k) order[k - first] = k;
            auto distance = [&](uint32_t k) { return glm::length(glm::dvec3(s.position(set, int(k))) - centre); };
            std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return distance(a) < distance(b); });
            order.resize(std::min<size_t>(order.size(), size_t(std::max(1, count))));
            out[size_t(set) * s.lightCount() + li] = std::move(order);
        }
        first = end;
    }
    return out;
}

}  // namespace

VisibilityMasks castSsv(const LightSamples& samples, const ReceiverSet& receivers, std::span<const uint32_t> sampleSetOf,
                        std::span<const Triangle> triangles, const ReceiverEpsilon& epsilon, const SsvOptions& options,
                        SsvStats* stats, const std::function<void(uint64_t)>& progress) {
    KdBox receiverBox;
    for (const glm::vec3& p : receivers.position)
        if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) receiverBox.add(glm::dvec3(p));
    const SsvScene scene(triangles, samples, epsilon, receiverBox, options.tree);

    Stopwatch castWatch;
    Context c{samples, scene, sampleSetOf, epsilon, options, options.alpha ? *options.alpha : *AlphaTable::builtin(),
              {}, {}, {}, {}, {}, {}, 0.0};
    for (const glm::vec3& p : samples.positions) c.sx.push_back(p.x), c.sy.push_back(p.y), c.sz.push_back(p.z);
    c.refs = referenceCandidates(samples, options.referenceCandidates);
    for (const LightSampleGroup& g : samples.groups) {
        double m = 0;
        for (const glm::dvec3& v : g.bound.vertices) m = std::max(m, maxAbs(v));
        c.groupMaxAbs.push_back(m);
    }
    c.lightFirstSample.push_back(0);
    for (int li = 0; li < samples.lightCount(); ++li) {
        uint32_t end = c.lightFirstSample.back();
        while (end < uint32_t(samples.sampleCount) && samples.sampleLight[end] == uint32_t(li)) ++end;
        c.lightFirstSample.push_back(end);
    }
    KdBox all = receiverBox;
    for (int li = 0; li < samples.lightCount(); ++li) all.add(scene.light(li).tree.bounds().lo), all.add(scene.light(li).tree.bounds().hi);
    if (!scene.alphaFaces().empty()) all.add(scene.alphaTree().bounds().lo), all.add(scene.alphaTree().bounds().hi);
    c.margin = all.empty() ? 1e-9 : 1e-7 * std::max({1e-300, maxAbs(all.lo), maxAbs(all.hi)});

    VisibilityMasks masks(receivers.size(), samples.groupCount());
    tbb::enumerable_thread_specific<ReceiverCaster> casters([&] { return ReceiverCaster(c); });
    tbb::enumerable_thread_specific<Local> locals;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, receivers.size(), 16), [&](const tbb::blocked_range<size_t>& range) {
        ReceiverCaster& caster = casters.local();
        Local& local = locals.local();
        for (size_t r = range.begin(); r != range.end(); ++r) {
            const glm::dvec3 p(receivers.position[r]);
            if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
            caster.cast(uint32_t(r), p, masks.row(r), local);
        }
        if (progress) progress(range.size());
    });

    if (stats) {
        SsvStats& st = *stats;
        st = SsvStats{};
        st.buildSeconds = scene.stats().buildSeconds;
        st.castSeconds = castWatch.seconds();
        st.receivers = receivers.size();
        st.faces = scene.stats().faces, st.alphaFaces = scene.stats().alphaFaces;
        st.sceneBytes = scene.bytes();
        for (int li = 0; li < samples.lightCount(); ++li) {
            const SsvLight& l = scene.light(li);
            st.potentialEdges += l.edges.size(), st.straddlers += l.straddlers;
            st.treeBytes += l.tree.bytes(), st.treeNodes += l.tree.nodes(), st.treeLeaves += l.tree.leaves();
            st.treeReferences += l.tree.references(), st.treeDepth = std::max(st.treeDepth, l.tree.depth());
        }
        for (const Local& l : locals) {
            st.frustums += l.frustums, st.edgesInFrustum += l.edges, st.silhouetteEdges += l.silhouettes;
            st.bandEdges += l.band, st.straddlersInFrustum += l.straddlers, st.referenceTriangles += l.refTriangles;
            st.referenceRetries += l.retries, st.fallbackFrustums += l.fallbacks;
            st.alphaInFrustum += l.alphaFaces, st.alphaTests += l.alphaTests;
        }
    }
    return masks;
}

nlohmann::json ssvStatsJson(const SsvStats& s) {
    const double frustums = double(std::max<uint64_t>(1, s.frustums));
    return {{"build_time_s", s.buildSeconds},
            {"cast_time_s", s.castSeconds},
            {"time_per_receiver_us", s.receivers ? 1e6 * s.castSeconds / double(s.receivers) : 0.0},
            {"faces", s.faces},
            {"potential_silhouette_edges", s.potentialEdges},
            {"straddlers", s.straddlers},
            {"scene_bytes", s.sceneBytes},
            {"kd_tree", {{"bytes", s.treeBytes}, {"nodes", s.treeNodes}, {"leaves", s.treeLeaves},
                         {"references", s.treeReferences}, {"depth", s.treeDepth}}},
            {"frustums", s.frustums},
            {"edges_per_frustum", double(s.edgesInFrustum) / frustums},
            {"silhouette_edges_per_frustum", double(s.silhouetteEdges) / frustums},
            {"band_edges", s.bandEdges},
            {"straddlers_per_frustum", double(s.straddlersInFrustum) / frustums},
            {"reference_triangles_per_frustum", double(s.referenceTriangles) / frustums},
            {"reference_retries", s.referenceRetries},
            {"fallback_frustums", s.fallbackFrustums},
            {"alpha_faces", s.alphaFaces},
            {"alpha_faces_per_frustum", double(s.alphaInFrustum) / frustums},
            {"alpha_tests", s.alphaTests}};
}

}  // namespace penumbra

namespace penumbra {
namespace {

/// Soft shadow volumes over the whole scene, with the paper's numbers (of the first pass: a
/// refinement's few receivers would hide them).
class SsvSceneCaster final : public SceneCaster {
public:
    explicit SsvSceneCaster(const CastContext& c)
        : SceneCaster(c, "ssv", [this](const ReceiverSet& targets, std::span<const uint32_t> sets,
                                       std::span<const Triangle> all, const std::function<void(uint64_t)>& progress) {
              SsvStats s;
              SsvOptions o;
              o.alpha = &alphaTableOf(c_.options);
              VisibilityMasks m = castSsv(c_.samples, targets, sets, all, receiverEpsilonOf(c_.options), o, &s, progress);
              if (!cast_) stats_ = s;
              cast_ = true;
              return m;
          }) {}

    nlohmann::json methodStats() const override { return ssvStatsJson(stats_); }

private:
    SsvStats stats_;
    bool cast_ = false;
};

const CasterRegistration kSsv{
    {"ssv",
     {.holdsScene = true,
      .summary = "soft shadow volumes (Laine et al. 2005) with frustum shooting: exact, holds the scene's edges"},
     [](const CastContext& c) { return std::make_unique<SsvSceneCaster>(c); },
     [](uint64_t triangles, uint64_t receivers, const LightSamples& samples, const nlohmann::json&) {
         // The scene read once, its faces, edges and kd-trees, and the masks of every receiver.
         return triangles * sizeof(Triangle) + SsvScene::plannedBytes(triangles, samples.lightCount()) +
                receivers * uint64_t(samples.groupCount()) * sizeof(uint64_t);
     },
     nullptr}};

}  // namespace
}  // namespace penumbra
