#include "bake/light/Light.h"

#include "stream/util/Error.h"

#include <glm/geometric.hpp>
#include <glm/gtc/constants.hpp>
#include <glm/trigonometric.hpp>
#include <glm/vec2.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace penumbra {
namespace {

struct Frame {
    glm::dvec3 origin, u, v, n;  // u, v, n orthonormal
};

glm::dvec3 anyPerpendicular(const glm::dvec3& n) {
    glm::dvec3 a = std::abs(n.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    return glm::normalize(glm::cross(n, a));
}

glm::dvec3 polygonNormal(const std::vector<glm::dvec3>& p) {
    glm::dvec3 n(0.0);  // Newell's method: robust for nearly collinear first vertices
    for (size_t i = 0; i < p.size(); ++i) {
        const glm::dvec3& a = p[i];
        const glm::dvec3& b = p[(i + 1) % p.size()];
        n += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    }
    return n;
}

Frame planarFrame(const LightDesc& l) {
    Frame f;
    switch (l.type) {
        case LightType::Rect:
            f.origin = l.center;
            f.n = glm::normalize(glm::cross(l.u, l.v));
            f.u = glm::normalize(l.u);
            break;
        case LightType::Disk:
        case LightType::Sun:  // (a sun arrives here as its disk of directions, sunDirectionDisk())
            f.origin = l.center;
            f.n = glm::normalize(l.normal);
            f.u = anyPerpendicular(f.n);
            break;
        default: {
            f.origin = std::accumulate(l.polygon.begin(), l.polygon.end(), glm::dvec3(0.0)) / double(l.polygon.size());
            f.n = glm::normalize(polygonNormal(l.polygon));
            f.u = glm::normalize(l.polygon[1] - l.polygon[0]);
            f.u = glm::normalize(f.u - glm::dot(f.u, f.n) * f.n);
        }
    }
    f.v = glm::cross(f.n, f.u);
    return f;
}

/// Factor n into a near-square (or near-cube) grid so strata are as compact as possible.
std::vector<int> gridDims(int n, int dims) {
    if (dims == 2) {
        int a = int(std::sqrt(double(n)));
        while (n % a) --a;
        return {n / a, a};
    }
    int best[3] = {n, 1, 1};
    double bestScore = INFINITY;
    for (int a = 1; a <= n; ++a) {
        if (n % a) continue;
        for (int b = 1; b <= n / a; ++b) {
            if ((n / a) % b) continue;
            int c = n / a / b;
            double score = double(std::max({a, b, c})) / std::min({a, b, c});
            if (score < bestScore) bestScore = score, best[0] = a, best[1] = b, best[2] = c;
        }
    }
    return {best[0], best[1], best[2]};
}

/// Maps a point of the canonical unit square (cube for spheres) onto the light.
glm::dvec3 mapCanonical(const LightDesc& l, const Frame& f, const glm::dvec3& c) {
    switch (l.type) {
        case LightType::Rect: return l.center + (c.x - 0.5) * l.u + (c.y - 0.5) * l.v;
        case LightType::Disk:
        case LightType::Sun: {  // Shirley-Chiu concentric map keeps strata compact
            double a = 2 * c.x - 1, b = 2 * c.y - 1, r, phi;
            if (a == 0 && b == 0) return l.center;
            if (std::abs(a) > std::abs(b)) r = a, phi = glm::quarter_pi<double>() * (b / a);
            else r = b, phi = glm::half_pi<double>() - glm::quarter_pi<double>() * (a / b);
            return l.center + l.radius * r * (std::cos(phi) * f.u + std::sin(phi) * f.v);
        }
        case LightType::Sphere: {
            // Three coordinates of a point uniform on the unit 3-sphere in R^4: the density in the
            // ball is 1 / (pi^2 sqrt(1 - r^2)), so every chord through it holds the same mass, and
            // seen from any receiver each direction of the sphere's cone gathers the same weight
            // per steradian once divided by d^2: a sphere of uniform radiance, exact in
            // expectation at any distance and across the receiver's horizon. Uniform in the ball,
            // the samples' mass crowded the cone's centre (E 12 % low with the centre on the
            // horizon, V too dark behind a central blocker).
            const double u = c.x, a = glm::two_pi<double>() * c.y, b = glm::pi<double>() * c.z;
            const double across = std::sqrt(u), along = std::sqrt(1 - u);
            return l.center + l.radius * glm::dvec3(across * std::cos(a), across * std::sin(a), along * std::cos(b));
        }
        case LightType::Polygon: {  // fan triangles, chosen by x in proportion to their area
            const auto& p = l.polygon;
            std::vector<double> areas;
            for (size_t i = 1; i + 1 < p.size(); ++i)
                areas.push_back(0.5 * glm::length(glm::cross(p[i] - p[0], p[i + 1] - p[0])));
            double total = std::accumulate(areas.begin(), areas.end(), 0.0), x = c.x * total;
            size_t i = 0;
            while (i + 1 < areas.size() && x > areas[i]) x -= areas[i++];
            double s = std::sqrt(std::clamp(x / areas[i], 0.0, 1.0));
            return (1 - s) * p[0] + s * (1 - c.y) * p[i + 1] + s * c.y * p[i + 2];
        }
    }
    return l.center;
}

/// Orders strata so that recursive median splits make spatially compact groups of <= groupSize.
void groupStrata(std::vector<int>& order, const std::vector<glm::dvec3>& centers, size_t begin, size_t end,
                 size_t groupSize, std::vector<std::pair<size_t, size_t>>& groups) {
    if (end - begin <= groupSize) {
        std::sort(order.begin() + begin, order.begin() + end);
        groups.push_back({begin, end});
        return;
    }
    glm::dvec3 lo(INFINITY), hi(-INFINITY);
    for (size_t i = begin; i < end; ++i) lo = glm::min(lo, centers[order[i]]), hi = glm::max(hi, centers[order[i]]);
    glm::dvec3 ext = hi - lo;
    int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    // Split so the left part is a whole number of groups: halves of 256 stay 64-aligned.
    size_t n = end - begin, groupsTotal = (n + groupSize - 1) / groupSize;
    size_t mid = begin + std::min(n - 1, (groupsTotal / 2) * groupSize);
    auto key = [&](int a, int b) {
        if (centers[a][axis] != centers[b][axis]) return centers[a][axis] < centers[b][axis];
        return a < b;
    };
    std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end, key);
    groupStrata(order, centers, begin, mid, groupSize, groups);
    groupStrata(order, centers, mid, end, groupSize, groups);
}

}  // namespace

double LightDesc::area() const {
    switch (type) {
        case LightType::Rect: return glm::length(glm::cross(u, v));
        case LightType::Disk: return glm::pi<double>() * radius * radius;
        case LightType::Sun: return 0.0;  // a cone of directions: no emitting area
        case LightType::Sphere: return 4.0 * glm::pi<double>() * radius * radius;
        case LightType::Polygon: return 0.5 * glm::length(polygonNormal(polygon));
    }
    return 0.0;
}

std::vector<glm::dvec3> LightDesc::outline() const {
    if (type == LightType::Polygon) return polygon;
    std::vector<glm::dvec3> corners;
    if (type == LightType::Rect)
        for (auto [a, b] : {std::pair{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}}) corners.push_back(center + a * u + b * v);
    return corners;
}

glm::dvec3 LightDesc::emitterNormal() const {
    switch (type) {
        case LightType::Rect: return glm::normalize(glm::cross(u, v));
        case LightType::Disk: return glm::normalize(normal);
        case LightType::Polygon: return glm::normalize(polygonNormal(polygon));
        default: return glm::dvec3(0.0);
    }
}

namespace {

/// Light coordinates and sizes must stay far from overflow: samples are float32, and the
/// blocking rule multiplies three coordinates (docs/scene-format.md, "Lights").
constexpr double kMaxLightCoordinate = 1e15;
/// Radiance and irradiance are written as float32; with this bound no sum over samples overflows.
constexpr double kMaxRadiance = 1e30;

void checkRange(const LightDesc& l, const char* key, const glm::dvec3& p, double bound) {
    for (int i = 0; i < 3; ++i)
        if (!(std::abs(p[i]) <= bound))
            fail(l.where, "{} [{}, {}, {}] is out of range (every component must be finite and at most {:g} in magnitude)",
                 key, p.x, p.y, p.z, bound);
}

void checkColour(const LightDesc& l, const char* key, const glm::dvec3& c) {
    for (int i = 0; i < 3; ++i)
        if (!(c[i] >= 0 && c[i] <= kMaxRadiance))
            fail(l.where, "{} [{}, {}, {}] must be finite, non-negative and at most {:g} per channel", key, c.x, c.y, c.z,
                 kMaxRadiance);
}

/// How far a polygon light's vertex may lie off the vertices' mean plane, relative to its size.
constexpr double kPolygonPlanarity = 1e-4;

/// The plane through a polygon's vertex mean with unit normal @p n, and its vertex farthest off it.
struct PolygonPlane {
    glm::dvec3 centre{0.0};
    size_t farthest = 0;
    double off = 0;  ///< the farthest vertex's distance from the plane
};

/// A polygon's size: its vertices' largest distance from the first, the scale of its tolerances.
double polygonSize(const std::vector<glm::dvec3>& p) {
    double size = 0;
    for (const glm::dvec3& q : p) size = std::max(size, glm::length(q - p[0]));
    return size;
}

PolygonPlane polygonPlane(const std::vector<glm::dvec3>& p, const glm::dvec3& n) {
    PolygonPlane plane;
    for (const glm::dvec3& q : p) plane.centre += q / double(p.size());
    for (size_t i = 0; i < p.size(); ++i)
        if (const double d = std::abs(glm::dot(p[i] - plane.centre, n)); d > plane.off) plane.off = d, plane.farthest = i;
    return plane;
}

/// A convex polygon winds once: every vertex is on or left of every edge (seen along the normal),
/// no edge has zero length, and the exterior angles sum to one full turn (a doubled square and a
/// pentagram have every turn convex but wind twice).
void checkConvexPolygon(const LightDesc& l, const glm::dvec3& n, double scale) {
    const auto& p = l.polygon;
    const size_t m = p.size();
    const glm::dvec3 u = glm::normalize(glm::abs(n.x) < 0.9 ? glm::cross(n, glm::dvec3(1, 0, 0)) : glm::cross(n, glm::dvec3(0, 1, 0)));
    const glm::dvec3 v = glm::cross(n, u);
    // Planar to 1e-4 of its size: vertices typed to four decimals are 1e-5 off their plane (at
    // 1e-6 such a pentagon was refused). Measured from the vertices' mean plane, so that the
    // vertex named is the one off it, not the first one tested.
    if (const PolygonPlane plane = polygonPlane(p, n); plane.off > kPolygonPlanarity * scale)
        fail(l.where, "polygon vertex {} is {:.3g} off the plane of the vertices (at most {:.3g}, {:g} of the polygon's size, "
                      "is allowed)", plane.farthest, plane.off, kPolygonPlanarity * scale, kPolygonPlanarity);
    double turning = 0.0;
    for (size_t i = 0; i < m; ++i) {
        const glm::dvec3 &a = p[i], &b = p[(i + 1) % m], &c = p[(i + 2) % m];
        if (!(glm::length(b - a) > 1e-12 * scale)) fail(l.where, "polygon vertices {} and {} coincide", i, (i + 1) % m);
        for (size_t j = 0; j < m; ++j)
            if (glm::dot(glm::cross(b - a, p[j] - a), n) < -1e-12 * scale * scale)
                fail(l.where, "polygon is not convex: vertex {} lies outside edge {}-{} (vertices must be in order, "
                              "winding once)", j, i, (i + 1) % m);
        const glm::dvec2 e0(glm::dot(b - a, u), glm::dot(b - a, v)), e1(glm::dot(c - b, u), glm::dot(c - b, v));
        turning += std::atan2(e0.x * e1.y - e0.y * e1.x, e0.x * e1.x + e0.y * e1.y);
    }
    if (std::abs(turning - glm::two_pi<double>()) > 1e-6)
        fail(l.where, "polygon winds {:.3g} times around its centre: list each vertex once, in order",
             turning / glm::two_pi<double>());
}

}  // namespace

void flattenPolygon(LightDesc& light) {
    std::vector<glm::dvec3>& p = light.polygon;
    if (light.type != LightType::Polygon || p.size() < 3) return;
    const double len = glm::length(polygonNormal(p));
    if (!(len > 0)) return;
    const glm::dvec3 n = polygonNormal(p) / len;
    const PolygonPlane plane = polygonPlane(p, n);
    // Within the old tolerance the vertices are kept bit for bit: their samples do not move.
    if (plane.off <= 1e-6 * polygonSize(p)) return;
    for (glm::dvec3& q : p) q -= glm::dot(q - plane.centre, n) * n;
}

void validateLight(const LightDesc& l) {
    if (l.samples < 1 || l.samples > 65536) fail(l.where, "samples must be in 1..65536, got {}", l.samples);
    if (l.sampleSets < 1 || l.sampleSets > 256) fail(l.where, "sample_sets must be in 1..256, got {}", l.sampleSets);
    switch (l.type) {
        case LightType::Rect:
            checkRange(l, "center", l.center, kMaxLightCoordinate);
            checkRange(l, "u", l.u, kMaxLightCoordinate), checkRange(l, "v", l.v, kMaxLightCoordinate);
            // Relative to |u| |v|: a whole scene in micrometres has lights of 1e-12 area, and a
            // disk or sphere of that size was always taken.
            if (const double area = glm::length(glm::cross(glm::dvec3(l.u), glm::dvec3(l.v)));
                !(area > 0) || !(area > 1e-9 * glm::length(glm::dvec3(l.u)) * glm::length(glm::dvec3(l.v))))
                fail(l.where, "zero-area light: u and v are zero or parallel (|u x v| = {:.3g}, at most 1e-9 of |u| |v|; "
                     "u=[{},{},{}], v=[{},{},{}])", area, l.u.x, l.u.y, l.u.z, l.v.x, l.v.y, l.v.z);
            break;
        case LightType::Sun:
            checkRange(l, "direction", l.direction, kMaxLightCoordinate);
            if (!(glm::length(l.direction) > 0)) fail(l.where, "direction must be a finite non-zero vector");
            if (!(l.angularDiameterDeg > 0 && l.angularDiameterDeg <= 20))
                fail(l.where, "angular_diameter_deg must be in (0, 20], got {}", l.angularDiameterDeg);
            checkColour(l, "irradiance", l.irradiance);
            return;
        case LightType::Disk:
            checkRange(l, "normal", l.normal, kMaxLightCoordinate);
            if (!(glm::length(l.normal) > 0)) fail(l.where, "normal is the zero vector");
            [[fallthrough]];
        case LightType::Sphere:
            checkRange(l, "center", l.center, kMaxLightCoordinate);
            if (!(l.radius > 0 && l.radius <= kMaxLightCoordinate))
                fail(l.where, "radius must be positive and at most {:g}, got {}", kMaxLightCoordinate, l.radius);
            break;
        case LightType::Polygon: {
            if (l.polygon.size() < 3) fail(l.where, "polygon needs at least 3 vertices, got {}", l.polygon.size());
            for (size_t i = 0; i < l.polygon.size(); ++i)
                checkRange(l, fmt::format("vertices[{}]", i).c_str(), l.polygon[i], kMaxLightCoordinate);
            glm::dvec3 n = polygonNormal(l.polygon);
            double len = glm::length(n);
            const double scale = polygonSize(l.polygon);
            if (!(len > 0) || !(len > 1e-9 * scale * scale)) fail(l.where, "zero-area light: polygon has no area");  // relative, as for rect
            checkConvexPolygon(l, n / len, scale);
        }
    }
    checkColour(l, "radiance", l.radiance);
}

LightDesc sunDirectionDisk(const LightDesc& sun) {
    LightDesc d = sun;
    const glm::dvec3 travel = glm::normalize(sun.direction);
    d.center = -travel;  // towards the sun, at unit distance
    d.normal = travel;   // the disk "emits" towards the scene
    d.radius = std::tan(glm::radians(sun.angularDiameterDeg) * 0.5);
    return d;
}

namespace {

/// How a light's samples are laid out: its strata grid and their order, grouped into
/// spatially compact ranges of at most @p groupSize (positions aside, all a plan needs).
struct LightLayout {
    LightDesc l;  ///< a sun as its disk of directions
    bool directional = false, volumetric = false;
    Frame frame;
    std::vector<int> dims, order;
    std::vector<std::pair<size_t, size_t>> ranges;

    glm::ivec3 strataCoord(int s) const {
        return glm::ivec3(s % dims[0], (s / dims[0]) % dims[1], volumetric ? s / (dims[0] * dims[1]) : 0);
    }
    glm::dvec3 canonical(glm::ivec3 c, glm::dvec3 jitter) const {
        glm::dvec3 p((c.x + jitter.x) / dims[0], (c.y + jitter.y) / dims[1], 0.0);
        if (volumetric) p.z = (c.z + jitter.z) / dims[2];
        return p;
    }
};

LightLayout layoutOf(const LightDesc& desc, int groupSize) {
    validateLight(desc);
    LightLayout out;
    out.directional = desc.type == LightType::Sun;
    out.l = out.directional ? sunDirectionDisk(desc) : desc;
    out.volumetric = out.l.type == LightType::Sphere;
    out.frame = out.volumetric ? Frame{} : planarFrame(out.l);
    out.dims = gridDims(out.l.samples, out.volumetric ? 3 : 2);
    std::vector<glm::dvec3> centers(out.l.samples);
    for (int s = 0; s < out.l.samples; ++s) centers[s] = mapCanonical(out.l, out.frame, out.canonical(out.strataCoord(s), glm::dvec3(0.5)));
    out.order.resize(out.l.samples);
    std::iota(out.order.begin(), out.order.end(), 0);
    groupStrata(out.order, centers, 0, out.order.size(), size_t(groupSize), out.ranges);
    return out;
}

void checkGroupSize(int groupSize) {
    if (groupSize < 1 || groupSize > 64) throw InputError(fmt::format("group_size must be in 1..64, got {}", groupSize));
}

}  // namespace

LightSamples lightSampleLayout(const std::vector<LightDesc>& lights, int groupSize) {
    checkGroupSize(groupSize);
    LightSamples out;
    out.sets = 1;
    for (const auto& l : lights) out.sets = std::max(out.sets, l.sampleSets), out.sampleCount += l.samples;
    uint32_t firstSample = 0;
    for (size_t li = 0; li < lights.size(); ++li) {
        const LightLayout layout = layoutOf(lights[li], groupSize);
        out.lightFirstGroup.push_back(uint32_t(out.groups.size()));
        out.lightBounds.emplace_back().w = layout.directional ? 0.0 : 1.0;
        for (auto [begin, end] : layout.ranges) {
            LightSampleGroup g;
            g.light = uint32_t(li), g.first = uint32_t(firstSample + begin), g.count = uint32_t(end - begin);
            out.groups.push_back(std::move(g));
        }
        firstSample += uint32_t(layout.l.samples);
    }
    out.lightFirstGroup.push_back(uint32_t(out.groups.size()));
    return out;
}

LightSamples generateLightSamples(const std::vector<LightDesc>& lights, int groupSize, uint64_t seed) {
    checkGroupSize(groupSize);
    LightSamples out;
    out.sets = 1;
    for (const auto& l : lights) out.sets = std::max(out.sets, l.sampleSets), out.sampleCount += l.samples;
    out.positions.resize(size_t(out.sets) * out.sampleCount);

    int firstSample = 0;
    for (size_t li = 0; li < lights.size(); ++li) {
        const LightLayout layout = layoutOf(lights[li], groupSize);
        const LightDesc& l = layout.l;
        const bool directional = layout.directional, volumetric = layout.volumetric;
        const Frame& frame = layout.frame;
        for (int set = 0; set < out.sets; ++set) {
            int ownSet = set % l.sampleSets;
            for (int k = 0; k < l.samples; ++k) {
                int stratum = layout.order[k];
                Rng rng(hashIndex(seed, li, ownSet, stratum));
                glm::dvec3 jitter(rng.uniform(), rng.uniform(), rng.uniform());
                out.positions[size_t(set) * out.sampleCount + firstSample + k] =
                    glm::vec3(mapCanonical(l, frame, layout.canonical(layout.strataCoord(stratum), jitter)));
            }
        }

        auto gather = [&](size_t begin, size_t end) {
            std::vector<glm::dvec3> pts;
            for (int set = 0; set < out.sets; ++set)
                for (size_t k = begin; k < end; ++k) pts.push_back(glm::dvec3(out.position(set, firstSample + int(k))));
            return pts;
        };
        auto bound = [&](const std::vector<glm::dvec3>& pts, bool withOutline) {
            if (volumetric) return boundPoints3D(pts);
            return boundPlanarPoints(pts, frame.origin, frame.u, frame.v, frame.n, withOutline ? l.outline() : std::vector<glm::dvec3>());
        };

        out.lightFirstGroup.push_back(uint32_t(out.groups.size()));
        out.lightBounds.push_back(bound(gather(0, l.samples), true));
        out.lightBounds.back().w = directional ? 0.0 : 1.0;
        for (auto [begin, end] : layout.ranges) {
            LightSampleGroup g;
            g.light = uint32_t(li);
            g.first = uint32_t(firstSample + begin);
            g.count = uint32_t(end - begin);
            g.bound = bound(gather(begin, end), false);
            g.bound.w = directional ? 0.0 : 1.0;
            out.groups.push_back(std::move(g));
        }
        out.sampleLight.insert(out.sampleLight.end(), size_t(l.samples), uint32_t(li));
        firstSample += l.samples;
    }
    out.lightFirstGroup.push_back(uint32_t(out.groups.size()));
    return out;
}

}  // namespace penumbra
