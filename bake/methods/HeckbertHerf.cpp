#include "bake/methods/HeckbertHerf.h"
#include "stream/util/TexelIndex.h"

#include "bake/methods/StreamedCaster.h"
#include "stream/util/Error.h"
#include "stream/util/Progress.h"

#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>

namespace penumbra {
namespace {

/// One receiver polygon prepared for projection: its plane, its affine map from the plane to
/// texel units (the paper's parallelogram: corners p0, p0 + ea, p0 + eb) and a grid of its texels
/// holding the receiver of each (or -1).
struct Polygon {
    glm::dvec3 p0, n;      ///< a corner and the unit normal of the side the receivers face
    glm::dvec3 ga, gb;     ///< dual basis: plane point x has parameters (ga . (x - p0), gb . (x - p0))
    glm::dvec2 t0, ta, tb; ///< texel coordinates of p0, and of the two edge vectors
    /// The inverse of the texel map, for cut-outs: texel t0 + d is point p0 + d.x worldX + d.y
    /// worldY (false texelsInvertible: the texel parallelogram is degenerate)
    glm::dvec3 worldX{0.0}, worldY{0.0};
    bool texelsInvertible = false;
    int x0 = 0, y0 = 0, width = 0, height = 0;  ///< the texel box of its receivers
    std::vector<int32_t> grid;
    uint64_t sets = 0;     ///< bit s set when a receiver uses sample set s (s < 64; bit 63 for the rest)
    double eps = 0;
};

uint64_t setBit(uint32_t set) { return 1ull << std::min<uint32_t>(set, 63); }

/// Builds the polygons that have receivers.
std::vector<Polygon> preparePolygons(const ReceiverSet& receivers, std::span<const uint32_t> sets,
                                     const ReceiverPolygons& in, const ReceiverEpsilon& epsilon) {
    std::vector<std::vector<uint32_t>> members(in.polygons.size());
    for (uint32_t r = 0; r < receivers.size(); ++r) members[in.polygonOf[r]].push_back(r);
    std::vector<Polygon> out;
    for (size_t i = 0; i < in.polygons.size(); ++i) {
        if (members[i].empty()) continue;
        const ReceiverPolygon& src = in.polygons[i];
        Polygon p;
        p.p0 = src.position[0];
        const glm::dvec3 ea = src.position[1] - p.p0, eb = src.position[2] - p.p0, nn = glm::cross(ea, eb);
        const double length = glm::length(nn);
        if (!(length > 0)) continue;  // a degenerate polygon: its texels stay unblocked
        p.n = nn / length;
        glm::dvec3 facing(0.0);  // the receivers' side: their (shading) normals
        for (uint32_t r : members[i]) facing += glm::dvec3(receivers.normal[r]);
        if (glm::dot(facing, p.n) < 0) p.n = -p.n;
        p.ga = glm::cross(eb, nn) / glm::dot(ea, glm::cross(eb, nn));
        p.gb = glm::cross(nn, ea) / glm::dot(eb, glm::cross(nn, ea));
        p.t0 = src.texel[0], p.ta = src.texel[1] - src.texel[0], p.tb = src.texel[2] - src.texel[0];
        if (const double det = p.ta.x * p.tb.y - p.ta.y * p.tb.x; det != 0.0) {
            p.worldX = (p.tb.y * ea - p.ta.y * eb) / det, p.worldY = (p.ta.x * eb - p.tb.x * ea) / det;
            p.texelsInvertible = true;
        }
        glm::ivec2 lo(INT32_MAX), hi(INT32_MIN);
        for (uint32_t r : members[i]) lo = glm::min(lo, in.texelOf[r]), hi = glm::max(hi, in.texelOf[r]);
        p.x0 = lo.x, p.y0 = lo.y, p.width = hi.x - lo.x + 1, p.height = hi.y - lo.y + 1;
        p.grid.assign(size_t(p.width) * p.height, -1);
        double scale = 0;
        for (uint32_t r : members[i]) {
            const glm::ivec2 t = in.texelOf[r] - lo;
            p.grid[size_t(t.y) * p.width + t.x] = int32_t(r);
            p.sets |= setBit(sets[r]);
            scale = std::max(scale, epsilon.at(glm::dvec3(receivers.position[r])));
        }
        p.eps = scale;
        out.push_back(std::move(p));
    }
    return out;
}

/// Everything one polygon's projections share: the samples and where their mask bits go.
struct Context {
    const LightSamples& samples;
    std::span<const uint32_t> sets;
    std::vector<uint32_t> groupOf;  ///< per global sample: its group
    VisibilityMasks& masks;
    const AlphaTable* alpha;        ///< the cut-outs' table; null: cut-outs are opaque triangles
};

/// A cut-out blocker seen from one sample: a covered texel is in its hard shadow only where the
/// segment from the texel's point on the polygon to the sample meets an opaque part of it (the
/// same AlphaTable test as the exact methods, at the ray's barycentrics).
struct CutOutFromSample {
    const Triangle& t;
    const AlphaTable* table;
    uint32_t id;
    glm::dvec3 l;  ///< the sample (w = 1) or its direction (w = 0)
    double w;
    bool opaqueAt(const Polygon& p, const glm::dvec2& texel) const {
        if (!p.texelsInvertible) return true;
        const glm::dvec2 d = texel - p.t0;
        const glm::dvec3 x = p.p0 + d.x * p.worldX + d.y * p.worldY;
        return table->lookupAlong(id, t.v[0], t.v[1], t.v[2], x, w == 1.0 ? l - x : l).opaque;
    }
};

/// Scan-converts the convex polygon @p v (texel units, @p count corners) over @p p's texels and
/// sets sample @p k's bit of every receiver of set @p set whose texel centre it covers (and, for a
/// cut-out @p cut, where it is opaque).
uint64_t cover(const Polygon& p, const glm::dvec2* v, int count, uint32_t set, uint32_t k, Context& c,
               const CutOutFromSample* cut) {
    glm::dvec2 lo(INFINITY), hi(-INFINITY);
    for (int i = 0; i < count; ++i) lo = glm::min(lo, v[i]), hi = glm::max(hi, v[i]);
    const int xa = clampedTexel(std::ceil(lo.x - 0.5), p.x0, p.x0 + p.width), xb = clampedTexel(std::floor(hi.x - 0.5), p.x0 - 1, p.x0 + p.width - 1);
    const int ya = clampedTexel(std::ceil(lo.y - 0.5), p.y0, p.y0 + p.height), yb = clampedTexel(std::floor(hi.y - 0.5), p.y0 - 1, p.y0 + p.height - 1);
    if (xa > xb || ya > yb) return 0;
    double area = 0;
    for (int i = 0; i < count; ++i) area += v[i].x * v[(i + 1) % count].y - v[(i + 1) % count].x * v[i].y;
    if (!(std::abs(area) > 0)) return 0;
    const double orient = area > 0 ? 1.0 : -1.0;
    const uint32_t group = c.groupOf[k], bit = k - c.samples.groups[group].first;
    uint64_t covered = 0;
    for (int y = ya; y <= yb; ++y)
        for (int x = xa; x <= xb; ++x) {
            const int32_t r = p.grid[size_t(y - p.y0) * p.width + (x - p.x0)];
            if (r < 0 || c.sets[r] != set) continue;
            const glm::dvec2 q(x + 0.5, y + 0.5);
            bool inside = true;
            for (int i = 0; i < count && inside; ++i) {
                const glm::dvec2 a = v[i], b = v[(i + 1) % count];
                inside = orient * ((b.x - a.x) * (q.y - a.y) - (b.y - a.y) * (q.x - a.x)) >= 0;
            }
            if (!inside || (cut && !cut->opaqueAt(p, q))) continue;
            c.masks.row(size_t(r))[group] |= 1ull << bit;
            ++covered;
        }
    return covered;
}

/// Clips @p in (@p n corners, heights @p h above the polygon's plane) to h >= lo and h <= hi.
int clipSlab(const glm::dvec3* in, const double* h, int n, double lo, double hi, glm::dvec3* out) {
    glm::dvec3 buffer[8];
    double hb[8];
    int m = 0;
    for (int i = 0; i < n; ++i) {  // h >= lo
        const int j = (i + 1) % n;
        if (h[i] >= lo) buffer[m] = in[i], hb[m++] = h[i];
        if ((h[i] >= lo) != (h[j] >= lo)) {
            const double t = (lo - h[i]) / (h[j] - h[i]);
            buffer[m] = in[i] + t * (in[j] - in[i]), hb[m++] = lo;
        }
    }
    int k = 0;
    for (int i = 0; i < m; ++i) {  // h <= hi
        const int j = (i + 1) % m;
        if (hb[i] <= hi) out[k++] = buffer[i];
        if ((hb[i] <= hi) != (hb[j] <= hi)) out[k++] = buffer[i] + ((hi - hb[i]) / (hb[j] - hb[i])) * (buffer[j] - buffer[i]);
    }
    return k;
}

/// Projects blocker @p t from every sample the polygon's receivers use into its texels, from
/// either side of the polygon's plane: what lies between a sample and the plane, on the sample's
/// side, shadows it. (The paper's back-face test, a sample behind the plane lighting none of the
/// texels, holds for a closed surface only; an open sheet lit from behind is lit, and a closed
/// surface's other faces project over it from there.)
void shadePolygon(const Polygon& p, const Triangle& t, Context& c, HeckbertHerfStats& local) {
    glm::dvec3 v[3];
    double h[3];
    for (int i = 0; i < 3; ++i) v[i] = glm::dvec3(t.v[i]), h[i] = glm::dot(p.n, v[i] - p.p0);
    const bool above = std::max({h[0], h[1], h[2]}) > p.eps, below = std::min({h[0], h[1], h[2]}) < -p.eps;
    if (!above && !below) return;  // in the polygon's plane
    const double hBelow[3] = {-h[0], -h[1], -h[2]};
    const LightSamples& s = c.samples;
    const uint32_t alphaId = c.alpha ? alphaIdOf(t.flags) : 0;
    for (uint32_t set = 0; set < uint32_t(s.sets); ++set) {
        if (!(p.sets & setBit(set))) continue;
        for (uint32_t k = 0; k < uint32_t(s.sampleCount); ++k) {
            const glm::dvec3 l(s.position(int(set), int(k)));
            const double w = s.sampleW(k);
            // Height of the sample (w = 1) or of its direction (w = 0) above the plane; below it,
            // the heights are taken from the other side, so that the sample's side is up.
            const double signedHl = w == 1.0 ? glm::dot(p.n, l - p.p0) : glm::dot(p.n, l);
            if (!(signedHl > 0 ? above : signedHl < 0 && below)) continue;  // nothing on the sample's side
            const double hl = std::abs(signedHl);
            const double* hs = signedHl > 0 ? h : hBelow;
            if (w == 1.0 && std::min({hs[0], hs[1], hs[2]}) >= hl) continue;  // wholly beyond the sample
            glm::dvec3 clipped[5];
            const int n = clipSlab(v, hs, 3, p.eps, w == 1.0 ? hl * (1 - 1e-9) : INFINITY, clipped);
            if (n < 3) continue;
            glm::dvec2 texels[5];
            for (int i = 0; i < n; ++i) {
                // The plane's intersection, in signed heights: the same quotients from either side.
                const double hx = glm::dot(p.n, clipped[i] - p.p0);
                const glm::dvec3 x = w == 1.0 ? l + (clipped[i] - l) * (signedHl / (signedHl - hx)) : clipped[i] - l * (hx / signedHl);
                const glm::dvec3 q = x - p.p0;
                texels[i] = p.t0 + glm::dot(p.ga, q) * p.ta + glm::dot(p.gb, q) * p.tb;
            }
            ++local.projections;
            const CutOutFromSample cut{t, c.alpha, alphaId, l, w};
            local.coveredTexels += cover(p, texels, n, set, k, c, alphaId ? &cut : nullptr);
        }
    }
}

}  // namespace

VisibilityMasks castHeckbertHerf(const LightSamples& samples, const ReceiverSet& receivers,
                                 std::span<const uint32_t> sampleSets, TriangleSource& blockers,
                                 const ReceiverEpsilon& epsilon, const ReceiverPolygons& polygons,
                                 HeckbertHerfStats* stats, const std::function<void(uint64_t)>& progress,
                                 const AlphaTable* alpha) {
    Stopwatch watch;
    VisibilityMasks masks(receivers.size(), samples.groupCount());
    const std::vector<Polygon> prepared = preparePolygons(receivers, sampleSets, polygons, epsilon);
    Context c{samples, sampleSets, std::vector<uint32_t>(size_t(samples.sampleCount)), masks, alpha};
    for (uint32_t g = 0; g < uint32_t(samples.groupCount()); ++g)
        for (uint32_t j = 0; j < samples.groups[g].count; ++j) c.groupOf[samples.groups[g].first + j] = g;
    std::atomic<uint64_t> projections{0}, covered{0};
    HeckbertHerfStats local;
    local.polygons = prepared.size();
    blockers.rewind();
    std::vector<Triangle> chunk(kTriangleChunk);
    while (size_t read = blockers.read(chunk)) {
        const size_t n = dropNonCasting(std::span<Triangle>(chunk.data(), read));
        // Polygons own disjoint receivers, so their masks never share a row.
        tbb::parallel_for(size_t(0), prepared.size(), [&](size_t i) {
            HeckbertHerfStats counts;
            for (size_t t = 0; t < n; ++t) shadePolygon(prepared[i], chunk[t], c, counts);
            projections += counts.projections, covered += counts.coveredTexels;
        });
        local.trianglesRead += n;
        if (progress) progress(n);
    }
    local.projections = projections.load(), local.coveredTexels = covered.load();
    local.seconds = watch.seconds();
    if (stats) *stats = local;
    return masks;
}

nlohmann::json heckbertHerfStatsJson(const HeckbertHerfStats& s) {
    return {{"polygons", s.polygons},
            {"projections", s.projections},
            {"covered_texels", s.coveredTexels},
            {"triangles_read", s.trianglesRead},
            {"time_s", s.seconds}};
}

}  // namespace penumbra

namespace penumbra {
namespace {

/// Heckbert & Herf over the receiver kind's polygons, streaming the blockers once per cast.
class HeckbertHerfCaster final : public StreamedCaster {
public:
    explicit HeckbertHerfCaster(const CastContext& c) : StreamedCaster(c) {}

    void cast(TriangleSource& blockers, uint32_t first, const CastSink& sink) override {
        // Polygons belong to the kind's own receivers; lightmaps are never refined.
        if (!c_.polygons || first != 0 || c_.polygons->polygonOf.size() != c_.receivers.size())
            fail("--method", "hh needs every receiver on a receiver polygon (lightmap receivers)");
        Stopwatch watch;
        observeOnce(blockers);
        ProgressReporter progress("hh", blockers.sizeHint().value_or(0), c_.quiet);
        const VisibilityMasks masks = castHeckbertHerf(c_.samples, c_.receivers, c_.sampleSets, blockers, receiverEpsilonOf(c_.options),
                                                       *c_.polygons, &stats_, [&](uint64_t n) { progress.update(n); },
                                                       &alphaTableOf(c_.options));
        progress.done();
        report(watch, 0, uint32_t(c_.receivers.size()), [&](uint32_t r) { sink.masks(r, masks.row(r), false); });
    }

    nlohmann::json methodStats() const override { return heckbertHerfStatsJson(stats_); }

private:
    HeckbertHerfStats stats_;
};

const CasterRegistration kHeckbertHerf{
    {"hh",
     {.exact = false, .sortedBlockers = false, .needsPolygons = true,
      .summary = "Heckbert & Herf 1997 hard shadows accumulated into lightmap textures: approximate at texel edges"},
     [](const CastContext& c) {
         refuseMaxDistance(c, "hh");
         return std::make_unique<HeckbertHerfCaster>(c);
     },
     [](uint64_t, uint64_t receivers, const LightSamples& samples, const nlohmann::json&) {
         // Every receiver's masks, its place in its polygon's member list and texel grid (a
         // triangle's texel box is at most twice its texels), and the kind's polygon and texel of
         // it; polygons with receivers are at most one per receiver, prepared and as the kind has them.
         return receivers * (uint64_t(samples.groupCount()) * sizeof(uint64_t) + 4 + 2 * 4 + 12 +
                             sizeof(Polygon) + sizeof(ReceiverPolygon));
     },
     nullptr}};

}  // namespace
}  // namespace penumbra
