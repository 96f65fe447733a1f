#include "bake/methods/LightView.h"

#include "stream/util/BandLists.h"
#include "stream/util/TexelIndex.h"

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

/// Two unit vectors completing @p axis to an orthonormal frame.
void frame(const glm::dvec3& axis, glm::dvec3& e1, glm::dvec3& e2) {
    const glm::dvec3 helper = std::abs(axis.y) < 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
    e1 = glm::normalize(glm::cross(helper, axis));
    e2 = glm::cross(axis, e1);
}

constexpr int kBands = 64;  ///< row bands rasterized in parallel

/// Folds every receiver position into a value of type T: blocks of a fixed size are folded with
/// @p add in order and their results combined with @p join in block order
/// (tbb::parallel_deterministic_reduce), so sums have the same bits for any thread count.
template <class T, class Add, class Join>
T reduceReceivers(const ReceiverPoints& receivers, T identity, Add add, Join join) {
    constexpr size_t kGrain = 16384;
    return tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, receivers.size(), kGrain), identity,
        [&](const tbb::blocked_range<size_t>& range, T value) {
            for (size_t i = range.begin(); i < range.end(); ++i) add(value, glm::dvec3(receivers.position[i]));
            return value;
        },
        [&](T a, const T& b) {
            join(a, b);
            return a;
        },
        tbb::simple_partitioner());
}

/// A box as minima and maxima.
struct Extent {
    glm::dvec3 lo{INFINITY}, hi{-INFINITY};
    void add(const glm::dvec3& p) { lo = glm::min(lo, p), hi = glm::max(hi, p); }
    void add(const Extent& e) { lo = glm::min(lo, e.lo), hi = glm::max(hi, e.hi); }
};

/// A cut-out triangle's alpha test at a texel: the ray of the texel centre against the original
/// triangle (so a piece clipped at the near plane tests the same texture), as the camera does.
struct CutOut {
    const LightView& view;
    const Triangle& tri;
    const AlphaTable* table;
    uint32_t id;
    bool opaqueAt(double cx, double cy) const {
        const double sx = (2.0 * cx / view.res - 1.0) * view.halfExtent, sy = (2.0 * cy / view.res - 1.0) * view.halfExtent;
        // Perspective: rays from the centre through the texel; orthographic: parallel rays from
        // the texel's point on the origin plane.
        const glm::dvec3 o = view.ortho ? view.origin + sx * view.e1 + sy * view.e2 : view.origin;
        const glm::dvec3 d = view.ortho ? view.axis : view.axis + sx * view.e1 + sy * view.e2;
        return table->lookupAlong(id, tri.v[0], tri.v[1], tri.v[2], o, d).opaque;
    }
};

/// Scan-converts one projected triangle into rows [y0, y1) of @p map; with @p cutOut, only its
/// opaque texels.
void drawTriangle(const LightView& view, const ViewPoint (&p)[3], int y0, int y1, DepthMap& map, const CutOut* cutOut) {
    const double xmin = std::min({p[0].x, p[1].x, p[2].x}), xmax = std::max({p[0].x, p[1].x, p[2].x});
    const double ymin = std::min({p[0].y, p[1].y, p[2].y}), ymax = std::max({p[0].y, p[1].y, p[2].y});
    const int ya = clampedTexel(std::ceil(ymin - 0.5), y0, y1), yb = clampedTexel(std::floor(ymax - 0.5), y0 - 1, y1 - 1);
    const int xa = clampedTexel(std::ceil(xmin - 0.5), 0, map.res), xb = clampedTexel(std::floor(xmax - 0.5), -1, map.res - 1);
    // No texel centre in the box (an eighth of FLOWERS' small triangles): nothing below is needed.
    if (ya > yb || xa > xb) return;
    const double area = (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[2].x - p[0].x) * (p[1].y - p[0].y);
    if (!(std::abs(area) > 1e-12)) return;
    double lin[3];
    for (int i = 0; i < 3; ++i) lin[i] = view.linearDepth(p[i].z);
    // Edge i's function (u.x - cx)(v.y - cy) - (v.x - cx)(u.y - cy), u and v the other two
    // vertices, is a + bx cx + by cy; its sign against the area's says inside (a texel centre on an
    // edge is inside), and over the area it is the barycentric of vertex i.
    const double orient = area > 0 ? 1.0 : -1.0, inverseArea = 1.0 / std::abs(area);  // the e_i below are oriented
    double ea[3], ex[3], ey[3];
    for (int i = 0; i < 3; ++i) {
        const ViewPoint &u = p[(i + 1) % 3], &v = p[(i + 2) % 3];
        ea[i] = (u.x * v.y - v.x * u.y) * orient, ex[i] = (u.y - v.y) * orient, ey[i] = (v.x - u.x) * orient;
    }
    // Thin triangles cover a few texels of a long box (3 % of the box on GRIDS' bars), so each
    // row first narrows its columns to where every edge can be >= 0: edge i crosses 0 at
    // cx = -row_i / ex_i, and the computed e_i of a texel differs from the exact one by less than
    // err_i = 8u (|ea_i| + |ey_i| |cy| + |ex_i| |cx|), so the span is widened by err_i / |ex_i|,
    // its own rounding and a hundredth of a texel (for the rounding of its conversion to
    // columns). The texel test below still decides; the span only skips texels that it would
    // reject (a test pins that on ties, slivers and near-axis edges). The whole texel of slack it
    // had before made FLOWERS' rows test 6.8 M texels to draw 2.1 M, and the shadow map 12 %
    // slower.
    // Per edge, once per triangle: 1/ex_i, and err_i / |ex_i| (with the division's rounding) as
    // errBase_i + errPerRow_i |cy|.
    constexpr double u = 0x1p-53;
    const double cxMax = std::max(std::abs(xa + 0.5), std::abs(xb + 0.5));
    double inverseEx[3], errBase[3], errPerRow[3];
    for (int i = 0; i < 3; ++i) {
        inverseEx[i] = ex[i] != 0 ? 1.0 / ex[i] : 0.0;
        const double scale = 8 * u * std::abs(inverseEx[i]) * (1 + 8 * u);
        errBase[i] = scale * (std::abs(ea[i]) + std::abs(ex[i]) * cxMax), errPerRow[i] = scale * std::abs(ey[i]);
    }
    for (int y = ya; y <= yb; ++y) {
        const double cy = y + 0.5;
        const double row[3] = {ea[0] + ey[0] * cy, ea[1] + ey[1] * cy, ea[2] + ey[2] * cy};
        double lo = xa + 0.5, hi = xb + 0.5;
        for (int i = 0; i < 3; ++i) {
            if (ex[i] == 0) {  // e_i = row_i + 0 * cx = row_i exactly
                if (row[i] < 0) lo = INFINITY;
                continue;
            }
            const double cross = -row[i] * inverseEx[i];
            const double widen = errBase[i] + errPerRow[i] * cy + 8 * u * std::abs(cross) + 0.01;
            if (ex[i] > 0) lo = std::max(lo, cross - widen);
            else hi = std::min(hi, cross + widen);
        }
        if (!(lo <= hi)) continue;
        const int xlo = std::max(xa, int(std::ceil(lo - 0.5))), xhi = std::min(xb, int(std::floor(hi - 0.5)));
        for (int x = xlo; x <= xhi; ++x) {
            const double cx = x + 0.5;
            const double e0 = row[0] + ex[0] * cx, e1 = row[1] + ex[1] * cx, e2 = row[2] + ex[2] * cx;
            if (e0 < 0 || e1 < 0 || e2 < 0) continue;
            if (cutOut && !cutOut->opaqueAt(cx, cy)) continue;
            const double b[3] = {e0 * inverseArea, e1 * inverseArea, e2 * inverseArea};
            const float z = float(view.fromLinear(b[0] * lin[0] + b[1] * lin[1] + b[2] * lin[2]));
            if (map.layers == 1) {
                float& d = map.depth[size_t(y) * map.res + x];
                d = std::min(d, z);
            } else {
                map.insert(size_t(y) * map.res + x, z, float(view.layerGap(z)));
            }
        }
    }
}

/// Clips @p t at the near plane (perspective views) and draws the pieces into rows [y0, y1).
void drawClipped(const LightView& view, const Triangle& t, int y0, int y1, DepthMap& map, const CutOut* cutOut) {
    glm::dvec3 in[3] = {glm::dvec3(t.v[0]), glm::dvec3(t.v[1]), glm::dvec3(t.v[2])};
    double d[3];
    int nearCount = 0;
    for (int i = 0; i < 3; ++i) d[i] = view.depth(in[i]) - view.zNear, nearCount += !(d[i] >= 0);
    if (nearCount == 3) return;
    glm::dvec3 poly[4];
    int n = 0;
    if (nearCount == 0) {
        poly[0] = in[0], poly[1] = in[1], poly[2] = in[2], n = 3;
    } else {
        for (int i = 0; i < 3; ++i) {
            const int j = (i + 1) % 3;
            if (d[i] >= 0) poly[n++] = in[i];
            if ((d[i] >= 0) != (d[j] >= 0)) poly[n++] = in[i] + (in[j] - in[i]) * (d[i] / (d[i] - d[j]));
        }
    }
    ViewPoint p[4];
    for (int i = 0; i < n; ++i) p[i] = view.project(poly[i]);
    for (int i = 1; i + 1 < n; ++i) {
        const ViewPoint tri[3] = {p[0], p[i], p[i + 1]};
        drawTriangle(view, tri, y0, y1, map, cutOut);
    }
}

}  // namespace

void DepthMap::reset(int resolution, int layerCount) {
    res = resolution, layers = layerCount;
    depth.assign(size_t(layers) * res * res, INFINITY);
}

bool DepthMap::holdsSurface(int layer) const {
    const auto plane = depth.begin() + ptrdiff_t(layer) * res * res;
    return std::any_of(plane, plane + ptrdiff_t(res) * res, [](float z) { return z < INFINITY; });
}

void DepthMap::insert(size_t index, float z, float gap) {
    const size_t plane = size_t(res) * res;
    float* d = &depth[index];
    int i = 0;
    while (i < layers && !(z <= d[i * plane] + gap)) ++i;  // the first layer z is not beyond
    if (i == layers) return;
    if (z >= d[i * plane] - gap) {  // the same layer: the nearer depth stays
        d[i * plane] = std::min(d[i * plane], z);
        return;
    }
    for (int j = layers - 1; j > i; --j) d[j * plane] = d[(j - 1) * plane];
    d[i * plane] = z;
}

ViewPoint LightView::project(const glm::dvec3& p) const {
    const glm::dvec3 d = p - origin;
    const double z = glm::dot(d, axis), scale = ortho ? halfExtent : z * halfExtent;
    return {0.5 * res * (1.0 + glm::dot(d, e1) / scale), 0.5 * res * (1.0 + glm::dot(d, e2) / scale), z};
}

glm::dvec3 lightCentre(const LightSamples& samples, int light) {
    const ConvexBound& bound = samples.lightBounds[size_t(light)];
    glm::dvec3 c(0.0);
    for (const glm::dvec3& v : bound.vertices) c += v;
    return c / double(std::max<size_t>(1, bound.vertices.size()));
}

namespace {

/// The support of the convex hull of @p points in direction @p n: the largest dot(n, point) (the
/// callers widen it for rounding).
double support(const glm::dvec3& n, std::span<const glm::dvec3> points) {
    double h = -INFINITY;
    for (const glm::dvec3& p : points) h = std::max(h, glm::dot(n, p));
    return h;
}

/// The eight corners of the box [lo, hi].
std::vector<glm::dvec3> corners(const glm::dvec3& lo, const glm::dvec3& hi) {
    std::vector<glm::dvec3> out;
    for (int i = 0; i < 8; ++i) out.push_back({i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z});
    return out;
}

/// Lateral directions of the region's side planes (every 45 degrees).
constexpr int kSides = 8;
glm::dvec2 side(int k) {
    const double a = glm::radians(45.0 * k);
    return {std::cos(a), std::sin(a)};
}

/// The half-spaces of the hull of the light's points @p light and the receivers, which lie inside
/// both @p box (a box of the frame) and, when given, @p frustum (the box of their tangents from the
/// centre between their nearest and farthest depths), as in ShadowReach: each side plane's support is
/// the larger of the light's and the receivers' (the smaller of their two bounds), so the region
/// holds every segment between them. The directions: sideways every 45 degrees and tilted towards
/// the axis by fixed slopes and by the slopes of the planes through the light's and the
/// receivers' extreme points (the penumbra's own sides), then along the axis and the light's
/// normal. Only their number decides how tight the region is, never whether it holds the hull.
std::vector<glm::dvec4> hullPlanes(std::span<const glm::dvec3> light, std::span<const glm::dvec3> box,
                                   std::span<const glm::dvec3> frustum, const glm::dvec3& lightNormal, double zNear, double zFar) {
    std::vector<glm::dvec3> normals = {{0, 0, 1}, {0, 0, -1}};
    if (glm::length(lightNormal) > 0) normals.push_back(lightNormal), normals.push_back(-lightNormal);
    for (int k = 0; k < kSides; ++k) {
        const glm::dvec2 m = side(k);
        std::vector<double> slopes = {0, 0.25, -0.25, 0.5, -0.5, 1, -1, 2, -2, 4, -4};
        double lightSide = -INFINITY;
        for (const glm::dvec3& p : light) lightSide = std::max(lightSide, glm::dot(m, glm::dvec2(p)));
        for (const std::span<const glm::dvec3> set : {box, frustum})
            for (const glm::dvec3& p : set)
                if (p.z > 0) slopes.push_back((lightSide - glm::dot(m, glm::dvec2(p))) / p.z);
        for (const double c : slopes) normals.push_back(glm::normalize(glm::dvec3(m, c)));
    }
    const double scale = 1e-9 * std::max(1.0, zFar) + zNear;
    std::vector<glm::dvec4> planes;
    for (const glm::dvec3& n : normals) {
        double receivers = support(n, box);
        if (!frustum.empty()) receivers = std::min(receivers, support(n, frustum));
        planes.push_back(glm::dvec4(n, std::max(support(n, light), receivers) + scale));
    }
    return planes;
}

/// Clips the convex polygon @p poly (n vertices) by dot(plane.xyz, q) <= plane.w; returns the count left.
int clipPolygon(glm::dvec3* poly, int n, glm::dvec3* scratch, const glm::dvec4& plane) {
    int m = 0;
    for (int i = 0; i < n; ++i) {
        const glm::dvec3 &a = poly[i], &b = poly[(i + 1) % n];
        const double da = glm::dot(glm::dvec3(plane), a) - plane.w, db = glm::dot(glm::dvec3(plane), b) - plane.w;
        if (da <= 0) scratch[m++] = a;
        if ((da <= 0) != (db <= 0)) scratch[m++] = a + (b - a) * (da / (da - db));
    }
    for (int i = 0; i < m; ++i) poly[i] = scratch[i];
    return m;
}

}  // namespace

double ShadowReach::extentNeeded(const LightView& view, const Triangle& t) const {
    glm::dvec3 q[3];
    double extent = 0;
    bool near = false;
    for (int i = 0; i < 3; ++i) {
        const glm::dvec3 d = glm::dvec3(t.v[i]) - origin;
        q[i] = {glm::dot(d, e1), glm::dot(d, e2), glm::dot(d, axis)};
        if (ortho) extent = std::max({extent, std::abs(q[i].x), std::abs(q[i].y)});
        else if (q[i].z >= zNear) extent = std::max({extent, std::abs(q[i].x) / q[i].z, std::abs(q[i].y) / q[i].z});
        else near = true;
    }
    // Inside the view (the most triangles): so is its part in the region.
    if (!near && extent <= view.halfExtent) return 0.0;
    // Each plane adds at most one vertex to a convex polygon.
    thread_local std::vector<glm::dvec3> poly, scratch;
    poly.resize(planes.size() + 5), scratch.resize(planes.size() + 5);
    poly[0] = q[0], poly[1] = q[1], poly[2] = q[2];
    int n = 3;
    // The near plane first: nearer parts are drawn in no view (rasterizeDepth() clips them).
    if (!ortho) n = clipPolygon(poly.data(), n, scratch.data(), glm::dvec4(0, 0, -1, -zNear));
    for (size_t i = 0; i < planes.size() && n > 0; ++i) n = clipPolygon(poly.data(), n, scratch.data(), planes[i]);
    extent = 0;
    for (int i = 0; i < n; ++i) {
        const glm::dvec3& p = poly[size_t(i)];
        if (ortho) extent = std::max({extent, std::abs(p.x), std::abs(p.y)});
        else extent = std::max({extent, std::abs(p.x) / std::max(p.z, zNear), std::abs(p.y) / std::max(p.z, zNear)});
    }
    return extent > view.halfExtent ? extent : 0.0;
}

std::vector<LightView> makeLightViews(const LightSamples& samples, int light, const ReceiverPoints& receivers, int resolution,
                                      int cubeResolution, double minimumExtent, ShadowReach* reach) {
    const glm::dvec3 c = lightCentre(samples, light);
    const ConvexBound& bound = samples.lightBounds[size_t(light)];
    std::vector<LightView> views;
    if (reach) *reach = ShadowReach{};
    if (bound.directional()) {
        LightView v;
        v.ortho = true, v.res = resolution, v.axis = -glm::normalize(c);
        frame(v.axis, v.e1, v.e2);
        double tanRadius = 0;  // the sun's angular radius
        for (const glm::dvec3& d : bound.vertices)
            tanRadius = std::max(tanRadius, glm::length(d - glm::dot(d, -v.axis) * -v.axis) / glm::dot(d, -v.axis));
        // The receivers' box in the view's axes (minima and maxima: any order gives the same bits).
        const Extent box = reduceReceivers(receivers, Extent{}, [&](Extent& e, const glm::dvec3& p) {
            e.add(glm::dvec3(glm::dot(p, v.e1), glm::dot(p, v.e2), glm::dot(p, v.axis)));
        }, [](Extent& a, const Extent& b) { a.add(b); });
        glm::dvec2 lo(box.lo), hi(box.hi);
        double zlo = box.lo.z, zhi = box.hi.z;
        if (receivers.size() == 0) lo = hi = glm::dvec2(0), zlo = zhi = 0;
        const double margin = tanRadius * (zhi - zlo) + 0.02 * std::max(hi.x - lo.x, hi.y - lo.y) + 1e-6;
        const glm::dvec2 mid = 0.5 * (lo + hi);
        v.origin = mid.x * v.e1 + mid.y * v.e2;
        // At least the extent that the blockers read in a view without it needed (drawMaps()).
        v.halfExtent = std::max(0.5 * std::max(hi.x - lo.x, hi.y - lo.y) + margin, minimumExtent * (1 + 4.0 / resolution));
        v.zNear = -INFINITY, v.zFar = zhi;
        views.push_back(v);
        if (reach && receivers.size() > 0) {
            // The receivers' box swept towards the sun along its cone: a side plane (m, c) with c
            // at least the largest m . t over the sun's tangent offsets t is never crossed going
            // towards the sun, so its support is the box's. The blockers far up beside the
            // receivers are what a box grown by the receivers' own depth range missed.
            reach->ortho = true, reach->origin = v.origin, reach->axis = v.axis, reach->e1 = v.e1, reach->e2 = v.e2;
            const std::vector<glm::dvec3> boxCorners = corners(glm::dvec3(lo - mid, zlo), glm::dvec3(hi - mid, zhi));
            const double scale = 1e-9 * std::max({1.0, std::abs(zlo), std::abs(zhi), hi.x - lo.x, hi.y - lo.y});
            reach->planes.push_back({0, 0, 1, zhi + scale});
            for (int k = 0; k < kSides; ++k) {
                const glm::dvec2 m = side(k);
                double cone = -INFINITY;
                for (const glm::dvec3& d : bound.vertices)
                    cone = std::max(cone, glm::dot(m, glm::dvec2(glm::dot(d, v.e1), glm::dot(d, v.e2))) / glm::dot(d, -v.axis));
                for (const double extra : {0.0, 0.5, 2.0}) {
                    const glm::dvec3 n(m, cone + extra);
                    reach->planes.push_back(glm::dvec4(n, support(n, boxCorners) + scale));
                }
            }
        }
        return views;
    }
    // The axis: the mean direction from the centre of at most about 65,536 receivers spread
    // evenly over the set (any axis near the middle serves; the angle below covers them all).
    glm::dvec3 mean(0.0);
    const size_t stride = std::max<size_t>(1, receivers.size() / 65536);
    for (size_t i = 0; i < receivers.size(); i += stride) {
        const glm::dvec3 d = glm::dvec3(receivers.position[i]) - c;
        const double length = glm::length(d);
        if (length > 0) mean += d / length;
    }
    // The widest angle from the axis is the acos of the smallest cosine: one acos, not one per
    // receiver (a million of them were most of the views' set-up). The same pass takes the
    // receivers' box in the view's frame and the box of their tangents from the centre (only
    // minima and maxima: the same bits for any thread count), which bound where the blockers
    // that can shadow them lie (ShadowReach).
    struct Spread {
        double smallestCosine = 1, farthest = 0;
        Extent box, tangents;  ///< frame coordinates; tangents (x / z, y / z, z) where z > 0
        bool behind = false;   ///< a receiver at depth <= 0: no box of tangents
    };
    const bool hasMean = glm::length(mean) > 1e-9;
    if (hasMean) mean = glm::normalize(mean);
    glm::dvec3 e1, e2;
    frame(hasMean ? mean : glm::dvec3(0, -1, 0), e1, e2);
    const Spread spread = reduceReceivers(receivers, Spread{}, [&](Spread& a, const glm::dvec3& p) {
        const glm::dvec3 d = p - c;
        const double length = glm::length(d);
        if (length > 0) a.smallestCosine = std::min(a.smallestCosine, glm::dot(d, mean) / length);
        a.farthest = std::max(a.farthest, length);
        const glm::dvec3 q(glm::dot(d, e1), glm::dot(d, e2), glm::dot(d, mean));
        a.box.add(q);
        if (q.z > 0) a.tangents.add(glm::dvec3(q.x / q.z, q.y / q.z, q.z));
        else a.behind = true;
    }, [](Spread& a, const Spread& b) {
        a.smallestCosine = std::min(a.smallestCosine, b.smallestCosine), a.farthest = std::max(a.farthest, b.farthest);
        a.box.add(b.box), a.tangents.add(b.tangents), a.behind = a.behind || b.behind;
    });
    const double farthest = spread.farthest, halfAngle = hasMean ? std::acos(std::clamp(spread.smallestCosine, -1.0, 1.0)) : 0.0;
    const double zNear = 1e-6 * std::max(farthest, 1e-300);
    // At least the angle that the blockers read in a view without it needed (drawMaps()).
    const double fitted = std::max(halfAngle, std::atan(std::max(minimumExtent, 0.0)));
    if (hasMean && fitted <= glm::radians(70.0)) {
        LightView v;
        v.origin = c, v.axis = mean, v.res = resolution, v.zNear = zNear, v.zFar = farthest;
        v.e1 = e1, v.e2 = e2;
        v.halfExtent = std::tan(std::min(fitted + glm::radians(3.0), glm::radians(73.0)));
        views.push_back(v);
        if (reach && receivers.size() > 0) {
            reach->origin = c, reach->axis = mean, reach->e1 = e1, reach->e2 = e2, reach->zNear = zNear;
            std::vector<glm::dvec3> lightPoints;
            for (const glm::dvec3& p : bound.vertices) lightPoints.push_back({glm::dot(p - c, e1), glm::dot(p - c, e2), glm::dot(p - c, mean)});
            // A planar light's normal (Newell's), so that the region stops at its plane.
            glm::dvec3 normal(0.0);
            for (size_t i = 0; i < lightPoints.size(); ++i) {
                const glm::dvec3 &a = lightPoints[i], &b = lightPoints[(i + 1) % lightPoints.size()];
                normal += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
            }
            bool planar = glm::length(normal) > 0;
            if (planar) {
                normal = glm::normalize(normal);
                for (const glm::dvec3& p : lightPoints) planar = planar && std::abs(glm::dot(normal, p - lightPoints[0])) <= 1e-9 * farthest;
            }
            const std::vector<glm::dvec3> box = corners(spread.box.lo, spread.box.hi);
            std::vector<glm::dvec3> frustum;
            if (!spread.behind)
                for (const glm::dvec3& t : corners(spread.tangents.lo, spread.tangents.hi)) frustum.push_back({t.x * t.z, t.y * t.z, t.z});
            reach->planes = hullPlanes(lightPoints, box, frustum, planar ? normal : glm::dvec3(0.0), zNear, farthest);
        }
        return views;
    }
    for (int face = 0; face < 6; ++face) {
        LightView v;
        v.origin = c, v.res = cubeResolution, v.zNear = zNear, v.zFar = farthest, v.halfExtent = 1.02;
        v.axis = glm::dvec3(0.0);
        v.axis[face / 2] = face % 2 ? -1.0 : 1.0;
        frame(v.axis, v.e1, v.e2);
        views.push_back(v);
    }
    return views;
}

bool viewsCover(const std::vector<LightView>& views, const ReceiverPoints& receivers, bool withinFar) {
    return reduceReceivers(receivers, true, [&](bool& covered, const glm::dvec3& p) {
        if (!covered) return;
        bool inside = false;
        for (const LightView& v : views) {
            const ViewPoint q = v.project(p);
            inside = inside || (q.z >= v.zNear && (!withinFar || q.z <= v.zFar) && q.x >= 0 && q.y >= 0 && q.x < v.res && q.y < v.res);
        }
        covered = inside;
    }, [](bool& a, bool b) { a = a && b; });
}

bool projectTriangle(const LightView& view, const Triangle& t, ViewPoint (&out)[3]) {
    for (int i = 0; i < 3; ++i) {
        out[i] = view.project(glm::dvec3(t.v[i]));
        if (!(out[i].z >= view.zNear) || !std::isfinite(out[i].x) || !std::isfinite(out[i].y)) return false;
    }
    return true;
}

void rasterizeDepth(const LightView& view, std::span<const Triangle> chunk, DepthMap& map, const AlphaTable* alpha) {
    // Project each triangle once, then let row bands draw the ones that reach them.
    struct Projected {
        ViewPoint p[3];
        bool clip;     ///< crosses the near plane: drawn through drawClipped
        int bandLo, bandHi;  ///< the row bands holding its texel rows (lo > hi: none)
    };
    const int rows = (map.res + kBands - 1) / kBands;
    std::vector<Projected> projected(chunk.size());
    tbb::parallel_for(size_t(0), chunk.size(), [&](size_t i) {
        Projected& q = projected[i];
        q.clip = !projectTriangle(view, chunk[i], q.p);
        if (q.clip) {  // its pieces may reach any row
            q.bandLo = 0, q.bandHi = kBands - 1;
            return;
        }
        // The rows and columns of texel centres in its box, as drawTriangle() finds them: the
        // bands beside them would draw nothing (they were a quarter of FLOWERS' calls), and a
        // box without a texel centre (an eighth of its triangles) reaches no band at all.
        const int ya = clampedTexel(std::ceil(std::min({q.p[0].y, q.p[1].y, q.p[2].y}) - 0.5), 0, map.res);
        const int yb = clampedTexel(std::floor(std::max({q.p[0].y, q.p[1].y, q.p[2].y}) - 0.5), -1, map.res - 1);
        const int xa = clampedTexel(std::ceil(std::min({q.p[0].x, q.p[1].x, q.p[2].x}) - 0.5), 0, map.res);
        const int xb = clampedTexel(std::floor(std::max({q.p[0].x, q.p[1].x, q.p[2].x}) - 0.5), -1, map.res - 1);
        q.bandLo = ya / rows, q.bandHi = ya <= yb && xa <= xb ? yb / rows : -1;
    });
    // Each band's triangles in stream order, so a band reads its own list, not the whole chunk:
    // with 64 bands the scan of every triangle per band cost more than drawing the small ones.
    BandLists lists;
    lists.build(kBands, projected.size(), [&](size_t i, int& lo, int& hi) { lo = projected[i].bandLo, hi = projected[i].bandHi; });
    const std::vector<uint32_t>&first = lists.first, &members = lists.members;
    tbb::parallel_for(0, kBands, [&](int band) {
        const int y0 = band * rows, y1 = std::min(map.res, y0 + rows);
        for (uint32_t m = first[size_t(band)]; m < first[size_t(band) + 1] && y0 < y1; ++m) {
            const size_t i = members[m];
            const Projected& q = projected[i];
            const CutOut cutOut{view, chunk[i], alpha, alpha ? alphaIdOf(chunk[i].flags) : 0};
            const CutOut* c = cutOut.id ? &cutOut : nullptr;
            if (q.clip) drawClipped(view, chunk[i], y0, y1, map, c);
            else drawTriangle(view, q.p, y0, y1, map, c);
        }
    });
}

}  // namespace penumbra
