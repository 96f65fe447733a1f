#include "bake/methods/PenumbraMap.h"

#include "bake/methods/Backprojection.h"
#include "bake/methods/LightView.h"
#include "stream/util/TexelIndex.h"
#include "bake/methods/StreamedCaster.h"
#include "stream/util/Error.h"
#include "stream/util/Progress.h"

#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>

namespace penumbra {
namespace {

constexpr int kBands = 64;  ///< row bands drawn in parallel

/// One light's view with its maps and the light's outline seen from its centre.
struct ViewMaps {
    LightView view;
    DepthMap shadow;
    std::vector<float> penumbra;        ///< per texel: the darkest intensity drawn (1: none)
    std::vector<glm::dvec2> outline;    ///< the light bound's vertices in image axes (world or tangent units)
    std::vector<float> tileFar;         ///< per kTile x kTile texels: the farthest surface (0: none); Wyman-Hansen only
    int tiles = 0;                      ///< tiles per side
    std::vector<DepthPyramid> pyramids;   ///< the backprojection lookup's coarse levels, per layer
    std::optional<LightGrid> grid;        ///< the light's outline as cells (backprojection)
    /// The farthest surface in the texel box [lo, hi] (conservative: whole tiles).
    float farthest(glm::dvec2 lo, glm::dvec2 hi) const;
};

constexpr int kTile = 16;
constexpr int kLayers = 4;  ///< depth layers of the backprojection lookup's shadow map

float ViewMaps::farthest(glm::dvec2 lo, glm::dvec2 hi) const {
    const int x0 = clampedTexel(std::floor(lo.x / kTile), 0, tiles - 1), x1 = clampedTexel(std::floor(hi.x / kTile), 0, tiles - 1);
    const int y0 = clampedTexel(std::floor(lo.y / kTile), 0, tiles - 1), y1 = clampedTexel(std::floor(hi.y / kTile), 0, tiles - 1);
    float z = 0;
    for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) z = std::max(z, tileFar[size_t(y) * tiles + x]);
    return z;
}

/// Fills @p m.tileFar from the finished shadow map.
void buildTiles(ViewMaps& m) {
    m.tiles = (m.view.res + kTile - 1) / kTile;
    m.tileFar.assign(size_t(m.tiles) * m.tiles, 0.0f);
    for (int y = 0; y < m.view.res; ++y)
        for (int x = 0; x < m.view.res; ++x) {
            const float z = m.shadow.at(x, y);
            float& t = m.tileFar[size_t(y / kTile) * m.tiles + x / kTile];
            if (std::isfinite(z)) t = std::max(t, z);
        }
}

/// A run of silhouette edge, projected: end points, their linear depths, and the light's half-width
/// across it.
struct Run {
    glm::dvec2 a, b;
    glm::dvec2 out;  ///< unit normal of the edge away from its triangle: sheets are drawn on that side
    double linA, linB;
    double radius;  ///< L_r: world units (perspective) or tangent of the angular radius (orthographic)
    double reach;   ///< texels beyond which the sheet is never darker than 1
};

/// The light's half-width across an image direction with unit normal @p m.
double halfWidth(const ViewMaps& v, const glm::dvec2& m) {
    double lo = INFINITY, hi = -INFINITY;
    for (const glm::dvec2& p : v.outline) lo = std::min(lo, glm::dot(p, m)), hi = std::max(hi, glm::dot(p, m));
    return v.outline.empty() ? 0.0 : 0.5 * (hi - lo);
}

float depthAt(const DepthMap& m, const glm::dvec2& q) {
    const int x = clampedTexel(std::floor(q.x), -1, m.res), y = clampedTexel(std::floor(q.y), -1, m.res);  // NaN: -1
    if (x < 0 || y < 0 || x >= m.res || y >= m.res) return INFINITY;
    return m.at(x, y);
}

/// The depth margin of the silhouette and shadow tests at depth @p z: the bias in texels, plus
/// @p slope (world depth per texel) times @p texels.
double gap(const LightView& view, double z, double bias, double slope, double texels) {
    return bias * view.texelWorld(z) + texels * slope;
}

/// Finds the silhouette runs of @p t's edges in @p v (read-only) and appends them to @p out.
void findRuns(const ViewMaps& v, const Triangle& t, double bias, std::vector<Run>& out) {
    const LightView& view = v.view;
    ViewPoint p[3];
    if (!projectTriangle(view, t, p)) return;
    double lin[3];
    for (int i = 0; i < 3; ++i) lin[i] = view.linearDepth(p[i].z);
    // The triangle's depth slope per texel, from its plane in (x, y, linear depth).
    const double area = (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[2].x - p[0].x) * (p[1].y - p[0].y);
    if (!(std::abs(area) > 1e-12)) return;
    const double gx = ((lin[1] - lin[0]) * (p[2].y - p[0].y) - (lin[2] - lin[0]) * (p[1].y - p[0].y)) / area;
    const double gy = ((lin[2] - lin[0]) * (p[1].x - p[0].x) - (lin[1] - lin[0]) * (p[2].x - p[0].x)) / area;
    const double linSlope = std::hypot(gx, gy);
    for (int e = 0; e < 3; ++e) {
        const ViewPoint &a = p[e], &b = p[(e + 1) % 3], &c = p[(e + 2) % 3];
        const glm::dvec2 A(a.x, a.y), B(b.x, b.y), dir = B - A;
        const double length = glm::length(dir);
        if (!(length > 1e-9)) continue;
        glm::dvec2 n(-dir.y / length, dir.x / length);
        if (glm::dot(n, glm::dvec2(c.x, c.y) - A) > 0) n = -n;  // away from the triangle
        const int steps = int(std::clamp(std::ceil(length), 1.0, 4096.0));
        int start = -1;
        auto close = [&](int end) {  // samples [start, end) are silhouette
            const double t0 = double(start) / steps, t1 = double(end) / steps;
            Run r;
            r.a = A + t0 * dir, r.b = A + t1 * dir, r.out = n;
            r.linA = lin[e] + t0 * (lin[(e + 1) % 3] - lin[e]), r.linB = lin[e] + t1 * (lin[(e + 1) % 3] - lin[e]);
            r.radius = halfWidth(v, n);
            // How far the sheet can reach: first to the farthest receiver, then only as far as the
            // farthest surface in the map around it.
            const double zv = std::min(view.fromLinear(r.linA), view.fromLinear(r.linB));
            auto reach = [&](double zFar) {
                const double spread = view.ortho ? r.radius * (zFar - zv) : r.radius * (zFar - zv) / (zv * zFar);
                return std::clamp(spread / view.texel(), 0.0, double(view.res));
            };
            r.reach = reach(view.zFar);
            r.reach = reach(std::min(view.zFar, double(v.farthest(glm::min(r.a, r.b) - r.reach, glm::max(r.a, r.b) + r.reach))));
            if (r.reach > 0 && r.radius > 0) out.push_back(r);
            start = -1;
        };
        for (int i = 0; i < steps; ++i) {
            const double s = (i + 0.5) / steps;
            const glm::dvec2 q = A + s * dir;
            const double lq = lin[e] + s * (lin[(e + 1) % 3] - lin[e]), zq = view.fromLinear(lq);
            const double slope = view.ortho ? linSlope : linSlope * zq * zq;  // world depth per texel
            const bool visible = depthAt(v.shadow, q) >= zq - gap(view, zq, bias, slope, 1.5);
            const bool silhouette = visible && depthAt(v.shadow, q + 1.5 * n) > zq + gap(view, zq, bias, slope, 3.0);
            if (silhouette && start < 0) start = i;
            if (!silhouette && start >= 0) close(i);
        }
        if (start >= 0) close(steps);
    }
}

/// The x-interval of row @p cy inside the outer half of @p run's capsule (the sheet and the end
/// cones, within reach of the segment, on the side away from the triangle); empty when lo > hi.
void rowSpan(const Run& run, double cy, double& lo, double& hi) {
    lo = INFINITY, hi = -INFINITY;
    const glm::dvec2 ab = run.b - run.a, n = run.out;
    const double length = glm::length(ab), R = run.reach;
    auto add = [&](double a, double b) {
        if (a <= b) lo = std::min(lo, a), hi = std::max(hi, b);
    };
    // x where a linear function f(x) = c0 + c1 x lies in [fmin, fmax], intersected with [a, b].
    auto clip = [](double c0, double c1, double fmin, double fmax, double& a, double& b) {
        if (c1 == 0) {
            if (c0 < fmin || c0 > fmax) a = INFINITY, b = -INFINITY;
            return;
        }
        double x0 = (fmin - c0) / c1, x1 = (fmax - c0) / c1;
        if (x0 > x1) std::swap(x0, x1);
        a = std::max(a, x0), b = std::min(b, x1);
    };
    for (const glm::dvec2& c : {run.a, run.b}) {  // end cones: disks clipped to the outer side
        const double dy = cy - c.y;
        if (std::abs(dy) > R) continue;
        const double w = std::sqrt(R * R - dy * dy);
        double a = c.x - w, b = c.x + w;
        clip(-run.a.x * n.x + (cy - run.a.y) * n.y, n.x, 0.0, INFINITY, a, b);
        add(a, b);
    }
    if (length > 0) {  // the sheet: a rectangle beside the segment
        const glm::dvec2 u = ab / length;
        double a = -INFINITY, b = INFINITY;
        clip(-run.a.x * u.x + (cy - run.a.y) * u.y, u.x, 0.0, length, a, b);
        clip(-run.a.x * n.x + (cy - run.a.y) * n.y, n.x, 0.0, R, a, b);
        add(a, b);
    }
}

/// Draws @p run's sheet and end cones into rows [y0, y1) of the penumbra map (darkest wins).
/// With lv = 1 / Z_v the paper's intensity becomes one division: perspective
/// I = a / ((L_r lv - a) (Z_P lv - 1)), orthographic I = (a / tan r) / (Z_P - Z_v).
void drawRun(ViewMaps& v, const Run& run, double bias, int y0, int y1) {
    const LightView& view = v.view;
    const int res = view.res;
    const glm::dvec2 lo = glm::min(run.a, run.b) - run.reach, hi = glm::max(run.a, run.b) + run.reach;
    const int ya = clampedTexel(std::floor(lo.y), y0, y1), yb = clampedTexel(std::ceil(hi.y), y0 - 1, y1 - 1);
    const glm::dvec2 ab = run.b - run.a;
    const double length = glm::length(ab), texel = view.texel();
    const glm::dvec2 u = length > 0 ? ab / length : glm::dvec2(0.0);
    const double gapTexels = bias * texel;  // the bias at depth z is gapTexels * z (perspective)
    for (int y = ya; y <= yb; ++y) {
        double x0, x1;
        rowSpan(run, y + 0.5, x0, x1);
        const int xa = clampedTexel(std::ceil(x0 - 0.5), 0, res), xb = clampedTexel(std::floor(x1 - 0.5), -1, res - 1);
        float* row = &v.penumbra[size_t(y) * res];
        const float* depth = &v.shadow.depth[size_t(y) * res];
        for (int x = xa; x <= xb; ++x) {
            if (!(row[x] > 0.0f)) continue;  // already as dark as it gets
            const double zp = depth[x];
            const glm::dvec2 d = glm::dvec2(x + 0.5, y + 0.5) - run.a;
            const double along = glm::dot(d, u), t = length > 0 ? std::clamp(along / length, 0.0, 1.0) : 0.0;
            const double across = glm::dot(d, run.out);
            const double distance = along >= 0 && along <= length ? across : glm::length(d - t * ab);
            const double lv = run.linA + t * (run.linB - run.linA), a = distance * texel;
            double i;
            if (view.ortho) {
                const double zgap = zp - lv;
                if (!(zgap > view.texelWorld(lv) * bias)) continue;  // the occluder itself, or nothing
                i = a / run.radius / zgap;
            } else {
                const double behind = zp * lv - 1.0, reach = run.radius * lv - a;
                if (!(behind > gapTexels) || !(reach > 0)) continue;  // Z_P - Z_v > bias Z_v; the cone reaches
                i = a / (reach * behind);
            }
            if (!(i <= 1.0)) continue;  // beyond the outer edge of this penumbra
            row[x] = std::min(row[x], float(i * i * (3.0 - 2.0 * i)));
        }
    }
}

/// Reads every chunk of @p blockers from the start, calling @p f with each chunk's casting
/// triangles (and @p observe, if set, with each chunk as read). The two run side by side: both
/// only read the chunk, and @p observe (the receiver kind's pass, smooth shading's vertex table
/// on FLOWERS: 0.12 s of one thread) still sees the chunks one after another, in order.
template <class F>
void forEachChunk(TriangleSource& blockers, PenumbraMapStats& stats, const std::function<void(uint64_t)>& progress, F&& f,
                  const std::function<void(std::span<const Triangle>)>& observe = {}) {
    blockers.rewind();
    std::vector<Triangle> chunk(kTriangleChunk), casting;
    while (size_t n = blockers.read(chunk)) {
        const std::span<const Triangle> read(chunk.data(), n);
        std::span<const Triangle> cast = read;
        if (std::any_of(read.begin(), read.end(), [](const Triangle& t) { return (t.flags & kTriangleNoCast) != 0; })) {
            casting.assign(read.begin(), read.end());
            cast = std::span<const Triangle>(casting.data(), dropNonCasting(casting));
        }
        if (observe) tbb::parallel_invoke([&] { observe(read); }, [&] { f(cast); });
        else f(cast);
        stats.trianglesRead += n;
        if (progress) progress(n);
    }
}

/// The depth along @p view's axis per unit of image offset of a light whose bound @p vertices
/// lie in one plane through @p c (0 otherwise, or when the view sees that plane nearly edge-on).
glm::dvec2 depthSlopeOf(const std::vector<glm::dvec3>& vertices, const glm::dvec3& c, const LightView& view) {
    if (vertices.size() < 3) return glm::dvec2(0.0);
    // The plane of the widest triangle of the vertices, from the first and the farthest from it.
    const glm::dvec3& a = vertices[0];
    glm::dvec3 b = a, normal(0.0);
    for (const glm::dvec3& v : vertices)
        if (glm::length(v - a) > glm::length(b - a)) b = v;
    for (const glm::dvec3& v : vertices)
        if (const glm::dvec3 n = glm::cross(b - a, v - a); glm::length(n) > glm::length(normal)) normal = n;
    const double size = glm::length(b - a);
    if (!(glm::length(normal) > 1e-12 * size * size)) return glm::dvec2(0.0);
    normal = glm::normalize(normal);
    for (const glm::dvec3& v : vertices)
        if (std::abs(glm::dot(v - c, normal)) > 1e-6 * size) return glm::dvec2(0.0);  // not flat: a sphere
    const double axis = glm::dot(view.axis, normal);
    if (!(std::abs(axis) > 0.05)) return glm::dvec2(0.0);
    return glm::dvec2(-glm::dot(view.e1, normal), -glm::dot(view.e2, normal)) / axis;
}

std::vector<ViewMaps> prepareViews(const LightSamples& samples, int li, const ReceiverPoints& receivers,
                                   const PenumbraMapOptions& options, double minimumExtent = 0, ShadowReach* reach = nullptr) {
    std::vector<ViewMaps> maps;
    const glm::dvec3 c = lightCentre(samples, li);
    const ConvexBound& bound = samples.lightBounds[size_t(li)];
    for (const LightView& view : makeLightViews(samples, li, receivers, options.resolution, options.resolution / 2, minimumExtent, reach)) {
        ViewMaps m;
        m.view = view;
        m.shadow.reset(view.res, options.lookup == PenumbraMapOptions::Lookup::Backprojection ? kLayers : 1);
        if (options.lookup == PenumbraMapOptions::Lookup::WymanHansen) m.penumbra.assign(size_t(view.res) * view.res, 1.0f);
        for (const glm::dvec3& p : bound.vertices) {
            if (bound.directional()) {  // tangent offsets of the sun's directions from its axis
                const double along = glm::dot(p, -view.axis);
                m.outline.push_back(glm::dvec2(glm::dot(p, view.e1), glm::dot(p, view.e2)) / along);
            } else {
                m.outline.push_back({glm::dot(p - c, view.e1), glm::dot(p - c, view.e2)});
            }
        }
        if (options.lookup == PenumbraMapOptions::Lookup::Backprojection) {
            m.grid.emplace(m.outline);
            if (!bound.directional()) m.grid->depthSlope = depthSlopeOf(bound.vertices, c, view);
        }
        maps.push_back(std::move(m));
    }
    return maps;
}

/// The visible fraction of receiver @p r from one light's maps.
float lookup(const std::vector<ViewMaps>& maps, const glm::dvec3& r, const glm::dvec3& normal, double bias, double eps, int taps) {
    const ViewMaps* best = &maps[0];
    if (maps.size() > 1) {  // a cube: the face the receiver's direction points through
        double deepest = best->view.depth(r);  // each face's depth once (twelve calls were half a lookup)
        for (const ViewMaps& m : maps)
            if (const double z = m.view.depth(r); z > deepest) best = &m, deepest = z;
    }
    const LightView& view = best->view;
    const ViewPoint p = view.project(r);
    // Clamped before the conversion: a receiver behind the light's centre projects anywhere.
    const int x = clampedTexel(std::floor(p.x), -1, view.res), y = clampedTexel(std::floor(p.y), -1, view.res);
    if (!(p.z >= view.zNear) || x < 0 || y < 0 || x >= view.res || y >= view.res) return 1.0f;
    if (best->grid && best->grid->hasArea()) return backprojectedVisibility(view, best->pyramids, *best->grid, r, normal, bias, eps, taps);
    const glm::dvec3 towards = view.ortho ? -view.axis : glm::normalize(view.origin - r);
    const double cosine = std::abs(glm::dot(normal, towards));
    const double slope = glm::length(normal) > 0 ? std::min(8.0, std::sqrt(std::max(0.0, 1 - cosine * cosine)) / std::max(cosine, 1e-3)) : 0.0;
    const double b = bias * view.texelWorld(p.z) * (1.0 + slope) + eps;
    if (double(best->shadow.at(x, y)) < p.z - b) return 0.0f;
    return best->penumbra.empty() ? 1.0f : best->penumbra[size_t(y) * view.res + x];
}

}  // namespace

uint64_t PenumbraMapOptions::mapBytes() const {
    const uint64_t fitted = uint64_t(resolution) * resolution, cube = 6 * uint64_t(resolution / 2) * (resolution / 2);
    const uint64_t texels = std::max(fitted, cube);
    if (lookup == Lookup::WymanHansen) return 2 * sizeof(float) * texels;
    // The layers of the shadow map and their pyramids (a third of the texels, 20 bytes each).
    return kLayers * (sizeof(float) * texels + std::max(DepthPyramid::plannedBytes(resolution), 6 * DepthPyramid::plannedBytes(resolution / 2)));
}

namespace {

/// Reads of the blockers that drawing one light's maps takes (the progress display's unit).
uint64_t readsPerLight(const PenumbraMapOptions& options) { return options.lookup == PenumbraMapOptions::Lookup::WymanHansen ? 2 : 1; }

/// Draws light @p li's maps over the streamed @p blockers: the shadow map, then the pyramids
/// (backprojection) or the penumbra map (Wyman-Hansen, a second read). @p observe, if set, sees
/// the first read.
std::vector<ViewMaps> drawMaps(const LightSamples& samples, int li, const ReceiverPoints& receivers, TriangleSource& blockers,
                               const PenumbraMapOptions& options, PenumbraMapStats& local,
                               const std::function<void(uint64_t)>& progress,
                               const std::function<void(std::span<const Triangle>)>& observe) {
    ShadowReach reach;
    std::vector<ViewMaps> maps = prepareViews(samples, li, receivers, options, 0.0, &reach);
    local.views += int(maps.size());
    {
        ScopedTimer timer(local.shadowSeconds);
        // The view is fitted to the receivers' directions from the light's centre, but what
        // shadows them lies in the hull of the light and the receivers, which under a wide light
        // reaches beyond those directions (a blocker that only the light's off-centre points see
        // behind a receiver). Where the blockers are is known only as they are read: the same
        // pass measures how wide a view their parts in the hull need (the largest over the
        // triangles: the same for any order and thread count), and when that is wider than the
        // view, the maps are drawn again in a view that wide, or in the cube beyond 70 degrees.
        // Most scenes' blockers lie inside the view, and the measure costs a projection per
        // triangle; the rest had light leaking into full shadow (clustered receivers under a
        // large blocker: up to 0.3 of the light in the umbra).
        double needed = 0;
        auto measure = [&](std::span<const Triangle> chunk) {
            if (reach.empty()) return;
            needed = std::max(needed, tbb::parallel_reduce(
                tbb::blocked_range<size_t>(0, chunk.size(), 1024), 0.0,
                [&](const tbb::blocked_range<size_t>& range, double value) {
                    for (size_t i = range.begin(); i < range.end(); ++i) value = std::max(value, reach.extentNeeded(maps[0].view, chunk[i]));
                    return value;
                },
                [](double a, double b) { return std::max(a, b); }));
        };
        forEachChunk(
            blockers, local, progress, [&](std::span<const Triangle> chunk) {
                for (ViewMaps& m : maps) rasterizeDepth(m.view, chunk, m.shadow, options.alpha);
                measure(chunk);
            },
            observe);
        if (!reach.empty() && needed > maps[0].view.halfExtent) {
            maps.clear();  // their memory first: the plan counts one light's maps
            maps = prepareViews(samples, li, receivers, options, needed);
            local.views += int(maps.size());
            ++local.viewsWidened;
            forEachChunk(blockers, local, {}, [&](std::span<const Triangle> chunk) {
                for (ViewMaps& m : maps) rasterizeDepth(m.view, chunk, m.shadow, options.alpha);
            });
        }
        // The tiles size the penumbra map's sheets; backprojection reads the pyramids instead
        // (a serial pass over the map, 3-4 % of FLOWERS' shadow-map time on two threads).
        if (options.lookup == PenumbraMapOptions::Lookup::WymanHansen)
            for (ViewMaps& m : maps) buildTiles(m);
    }
    uint64_t bytes = 0;
    for (const ViewMaps& m : maps) bytes += (m.shadow.depth.size() + m.penumbra.size()) * sizeof(float);
    ScopedTimer timer(local.penumbraSeconds);
    if (options.lookup == PenumbraMapOptions::Lookup::Backprojection) {
        for (ViewMaps& m : maps) {
            // Layer 0 always, the next ones while they hold a surface: a layer without one
            // would end every texel's loop over the layers at once (its depths are all +infinity,
            // and so are the layers' behind it), and its pyramid cost as much as a full one.
            int kept = 1;
            while (kept < m.shadow.layers && m.shadow.holdsSurface(kept)) ++kept;
            // The layers' pyramids side by side: each level's rows are parallel, but the coarse
            // levels have few rows, and one layer at a time left a thread idle there.
            std::vector<std::optional<DepthPyramid>> built(static_cast<size_t>(kept));
            tbb::parallel_for(0, kept, [&](int layer) { built[size_t(layer)].emplace(m.shadow, layer); }, tbb::simple_partitioner());
            m.pyramids.reserve(size_t(kept));
            for (std::optional<DepthPyramid>& p : built) m.pyramids.push_back(std::move(*p));
        }
        for (const ViewMaps& m : maps) bytes += m.pyramids.size() * DepthPyramid::plannedBytes(m.view.res);
    } else {
        std::vector<std::vector<Run>> perTriangle;
        std::vector<Run> runs;
        forEachChunk(blockers, local, progress, [&](std::span<const Triangle> chunk) {
            for (ViewMaps& m : maps) {
                perTriangle.assign(chunk.size(), {});
                tbb::parallel_for(size_t(0), chunk.size(), [&](size_t i) { findRuns(m, chunk[i], options.bias, perTriangle[i]); });
                runs.clear();
                for (const std::vector<Run>& r : perTriangle) runs.insert(runs.end(), r.begin(), r.end());
                local.silhouetteRuns += runs.size();
                const int rows = (m.view.res + kBands - 1) / kBands;
                tbb::parallel_for(0, kBands, [&](int band) {
                    const int y0 = band * rows, y1 = std::min(m.view.res, y0 + rows);
                    for (const Run& run : runs)
                        if (std::max(run.a.y, run.b.y) + run.reach >= y0 && std::min(run.a.y, run.b.y) - run.reach <= y1)
                            drawRun(m, run, options.bias, y0, y1);
                });
            }
        });
    }
    local.mapBytes = std::max(local.mapBytes, bytes);
    return maps;
}

std::vector<LightView> viewsOf(const std::vector<ViewMaps>& maps) {
    std::vector<LightView> views;
    for (const ViewMaps& m : maps) views.push_back(m.view);
    return views;
}

}  // namespace

struct PenumbraMapCache::Kept {
    int light = -1;
    std::vector<ViewMaps> maps;  ///< moved in whole: the pyramids point at their maps' shadow maps
};
PenumbraMapCache::PenumbraMapCache() = default;
PenumbraMapCache::~PenumbraMapCache() = default;
PenumbraMapCache::PenumbraMapCache(PenumbraMapCache&&) noexcept = default;
PenumbraMapCache& PenumbraMapCache::operator=(PenumbraMapCache&&) noexcept = default;

std::vector<float> castPenumbraMap(const LightSamples& samples, const ReceiverPoints& receivers,
                                   std::span<const uint32_t>, TriangleSource& blockers, const ReceiverEpsilon& epsilon,
                                   const PenumbraMapOptions& options, PenumbraMapStats* stats,
                                   const std::function<void(uint64_t)>& progress,
                                   const std::function<void(std::span<const Triangle>)>& observe, PenumbraMapCache* cache) {
    PenumbraMapStats local;
    const int lights = samples.lightCount();
    std::vector<float> visibility(receivers.size() * size_t(lights), 1.0f);
    // The kept light first, so that only the last light's maps need keeping for the next cast;
    // each light fills its own slot of every receiver, so the order does not change the result.
    const int keptLight = cache && cache->kept && cache->kept->light < lights ? cache->kept->light : -1;
    std::vector<int> order(size_t(std::max(lights, 0)));
    std::iota(order.begin(), order.end(), 0);
    if (keptLight >= 0) std::rotate(order.begin(), order.begin() + keptLight, order.begin() + keptLight + 1);
    // Only the penumbra map's sheets reach as far as the view's zFar (the farthest receiver it was
    // drawn for); backprojection reads any depth.
    const bool sheets = options.lookup == PenumbraMapOptions::Lookup::WymanHansen;
    std::function<void(std::span<const Triangle>)> unobserved = observe;  // until the first read
    for (const int li : order) {
        std::vector<ViewMaps> maps;
        if (li == keptLight && viewsCover(viewsOf(cache->kept->maps), receivers, sheets)) {
            maps = std::move(cache->kept->maps);
            ++local.mapsReused;
            if (progress) progress(readsPerLight(options) * blockers.sizeHint().value_or(0));  // the reads it saves count as done
        } else {
            if (cache) cache->kept.reset();  // its memory, before the next light's maps are drawn
            maps = drawMaps(samples, li, receivers, blockers, options, local, progress, unobserved);
            unobserved = {};
        }
        {
            ScopedTimer timer(local.lookupSeconds);
            tbb::parallel_for(size_t(0), receivers.size(), [&](size_t r) {
                const glm::dvec3 p(receivers.position[r]);
                visibility[r * lights + li] = lookup(maps, p, glm::dvec3(receivers.normal[r]), options.bias, epsilon.at(p), options.taps);
            });
        }
        if (cache && li == order.back()) {
            if (!cache->kept) cache->kept = std::make_unique<PenumbraMapCache::Kept>();
            cache->kept->light = li, cache->kept->maps = std::move(maps);
        }
    }
    if (unobserved) forEachChunk(blockers, local, {}, [](std::span<const Triangle>) {}, unobserved);
    if (stats) *stats = local;
    return visibility;
}

nlohmann::json penumbraMapStatsJson(const PenumbraMapStats& s, const PenumbraMapOptions& o) {
    return {{"resolution", o.resolution},
            {"lookup", o.lookup == PenumbraMapOptions::Lookup::WymanHansen ? "wyman-hansen" : "backprojection"},
            {"bias_texels", o.bias},
            {"taps", o.taps},
            {"views", s.views},
            {"maps_reused", s.mapsReused},
            {"views_widened", s.viewsWidened},
            {"map_bytes", s.mapBytes},
            {"shadow_map_time_s", s.shadowSeconds},
            {"penumbra_map_time_s", s.penumbraSeconds},
            {"lookup_time_s", s.lookupSeconds},
            {"silhouette_runs", s.silhouetteRuns},
            {"triangles_read", s.trianglesRead}};
}

}  // namespace penumbra

namespace penumbra {

PenumbraMapOptions penumbraMapOptions(const JsonParams& bake) {
    PenumbraMapOptions o;
    o.resolution = int(bake.integer("penumbra_map_resolution", o.resolution, 16, 16384));
    o.bias = bake.number("penumbra_map_bias", o.bias);
    // The option's range too (--penumbra-map-bias): a bias of a million texels already hides
    // every shadow, so a larger one is a typo.
    if (!(o.bias >= 0 && o.bias <= 1e6)) fail(bake.where("penumbra_map_bias"), "must be in 0..1000000, got {}", o.bias);
    o.taps = int(bake.integer("penumbra_map_taps", o.taps, 1, 8));
    const std::string lookup = bake.string("penumbra_map_lookup", "backprojection");
    if (lookup == "wyman-hansen") o.lookup = PenumbraMapOptions::Lookup::WymanHansen;
    else if (lookup != "backprojection")
        fail(bake.where("penumbra_map_lookup"), "must be \"backprojection\" or \"wyman-hansen\", got \"{}\"", lookup);
    return o;
}

namespace {

PenumbraMapOptions optionsOf(const nlohmann::json& bake) { return penumbraMapOptions(JsonParams(bake, "scene", "bake")); }

/// Penumbra maps per light, streaming the blockers twice per light and cast; gives visible fractions.
class PenumbraMapCaster final : public StreamedCaster {
public:
    explicit PenumbraMapCaster(const CastContext& c) : StreamedCaster(c), options_(optionsOf(c.methodOptions)) {
        options_.alpha = &alphaTableOf(c.options);
    }

    void cast(TriangleSource& blockers, uint32_t first, const CastSink& sink) override {
        // A refinement pass reads its receivers in place, and the last light's maps kept from the
        // pass before serve it when they cover its receivers.
        Stopwatch watch;
        const ReceiverPoints targets(c_.receivers, first);
        const int lights = c_.samples.lightCount();
        ProgressReporter progress("penumbra-map", readsPerLight(options_) * blockers.sizeHint().value_or(0) * uint64_t(lights), c_.quiet);
        PenumbraMapStats s;
        const std::vector<float> v = castPenumbraMap(c_.samples, targets, std::span<const uint32_t>(c_.sampleSets).subspan(first), blockers,
                                                     receiverEpsilonOf(c_.options), options_, &s, [&](uint64_t n) { progress.update(n); },
                                                     takeObserver(), &kept_);
        progress.done();
        // The first pass's stats: a refinement's few receivers would hide them; but say whether
        // the refinement drew its maps again.
        if (first == 0) stats_ = s;
        else stats_.mapsReused += s.mapsReused;
        report(watch, first, uint32_t(c_.receivers.size()),
                         [&](uint32_t r) { sink.visibility(r, &v[size_t(r - first) * size_t(lights)]); });
    }

    nlohmann::json methodStats() const override { return penumbraMapStatsJson(stats_, options_); }

private:
    PenumbraMapOptions options_;
    PenumbraMapStats stats_;
    PenumbraMapCache kept_;
};

const CasterRegistration kPenumbraMap{
    {"penumbra-map",
     {.exact = false, .masks = false, .sortedBlockers = false,
      .summary = "penumbra maps (Wyman & Hansen 2003): an approximate preview, visible fractions only"},
     [](const CastContext& c) {
         refuseMaxDistance(c, "penumbra-map");
         return std::make_unique<PenumbraMapCaster>(c);
     },
     [](uint64_t, uint64_t receivers, const LightSamples& samples, const nlohmann::json& bake) {
         // One light's maps at a time, and every receiver's visible fraction of every light.
         return optionsOf(bake).mapBytes() + receivers * uint64_t(samples.lightCount()) * sizeof(float);
     },
     [](const JsonParams& bake) { penumbraMapOptions(bake); }}};

}  // namespace
}  // namespace penumbra
