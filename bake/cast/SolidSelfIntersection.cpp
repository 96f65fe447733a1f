#include "bake/cast/SolidSelfIntersection.h"

#include "stream/util/Memory.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <utility>
#include <cmath>

namespace penumbra {
namespace {

using glm::dvec3;

constexpr double kU = 0x1p-53;  // unit roundoff of double
/// A corner is strictly beyond a plane through the shared corner when it is farther than this
/// share of |d|_1 |p - o|_inf: far above rounding, so that two faces folded onto each other
/// within rounding of one plane are never taken as separated.
constexpr double kStrictShare = 1e-9;

double norm1(const dvec3& v) { return std::abs(v.x) + std::abs(v.y) + std::abs(v.z); }
double normInf(const dvec3& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

/// d . p with a bound of its rounding, p being a difference of two floats formed in double.
struct Projection {
    double value, bound;
};
Projection project(const dvec3& d, const dvec3& p) {
    return {glm::dot(d, p), 16 * kU * (std::abs(d.x * p.x) + std::abs(d.y * p.y) + std::abs(d.z * p.z))};
}

/// The corners of a triangle that another does not share, relative to an origin (a shared corner).
struct Corners {
    dvec3 p[3];
    int n = 0;
};

/// Whether the plane through the origin with normal @p d has every corner of @p strict beyond it
/// (on side -1) by a clear margin and every corner of @p weak on side +1 up to rounding.
bool splits(const dvec3& d, const Corners& strict, const Corners& weak) {
    const double scale = norm1(d);
    for (int i = 0; i < strict.n; ++i) {
        const Projection s = project(d, strict.p[i]);
        if (!(s.value < -(s.bound + kStrictShare * scale * normInf(strict.p[i])))) return false;
    }
    for (int i = 0; i < weak.n; ++i) {
        const Projection s = project(d, weak.p[i]);
        if (!(s.value >= -s.bound)) return false;
    }
    return true;
}

/// Whether some orientation of @p d splits the corners, either triangle taking the strict side.
bool splitsEither(const dvec3& d, const Corners& a, const Corners& b) {
    if (!(norm1(d) > 0)) return false;
    const dvec3 m = -d;
    return splits(d, a, b) || splits(d, b, a) || splits(m, a, b) || splits(m, b, a);
}

/// Whether @p d separates the two triangles' corners (relative to one origin) with a gap above
/// rounding: triangles that do not share a corner.
bool gapAlong(const dvec3& d, const dvec3 a[3], const dvec3 b[3]) {
    if (!(norm1(d) > 0)) return false;
    double aLo = INFINITY, aHi = -INFINITY, bLo = INFINITY, bHi = -INFINITY;
    for (int i = 0; i < 3; ++i) {
        const Projection s = project(d, a[i]), t = project(d, b[i]);
        aLo = std::min(aLo, s.value - s.bound), aHi = std::max(aHi, s.value + s.bound);
        bLo = std::min(bLo, t.value - t.bound), bHi = std::max(bHi, t.value + t.bound);
    }
    return aHi < bLo || bHi < aLo;
}

bool disjoint(const dvec3 a[3], const dvec3 b[3]) {
    const dvec3 ea[3] = {a[1] - a[0], a[2] - a[1], a[0] - a[2]}, eb[3] = {b[1] - b[0], b[2] - b[1], b[0] - b[2]};
    const dvec3 na = glm::cross(ea[0], a[2] - a[0]), nb = glm::cross(eb[0], b[2] - b[0]);
    if (gapAlong(na, a, b) || gapAlong(nb, a, b)) return true;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            if (gapAlong(glm::cross(ea[i], eb[j]), a, b)) return true;
    for (int i = 0; i < 3; ++i)  // coplanar pairs: the edges' normals within each plane
        if (gapAlong(glm::cross(na, ea[i]), a, b) || gapAlong(glm::cross(nb, eb[i]), a, b)) return true;
    return false;
}

}  // namespace

bool trianglesMayCross(const SolidTriangle& ta, const SolidTriangle& tb) {
    int sharedA[3], sharedB[3], k = 0;
    bool aShared[3] = {false, false, false}, bShared[3] = {false, false, false};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            if (!bShared[j] && ta.v[i] == tb.v[j]) {
                sharedA[k] = i, sharedB[k] = j, ++k, aShared[i] = bShared[j] = true;
                break;
            }
    if (k == 3) return true;  // the same triangle twice, or flipped: a fin of no thickness
    const dvec3 o = k > 0 ? dvec3(ta.v[sharedA[0]]) : dvec3(ta.v[0]);
    dvec3 a[3], b[3];
    for (int i = 0; i < 3; ++i) a[i] = dvec3(ta.v[i]) - o, b[i] = dvec3(tb.v[i]) - o;
    if (k == 0) return !disjoint(a, b);

    // A plane through the shared corner (k = 1) or edge (k = 2) with one triangle's other
    // corners strictly beyond it and the other's on its side: the triangles meet only there.
    Corners ca, cb;
    dvec3 ua[2], wb[2];  // edges from the first shared corner to the other corners
    int nu = 0, nw = 0;
    for (int i = 0; i < 3; ++i) {
        if (!aShared[i]) ca.p[ca.n++] = a[i];
        if (!bShared[i]) cb.p[cb.n++] = b[i];
        if (i != sharedA[0]) ua[nu++] = a[i];
        if (i != sharedB[0]) wb[nw++] = b[i];
    }
    const dvec3 na = glm::cross(a[1] - a[0], a[2] - a[0]), nb = glm::cross(b[1] - b[0], b[2] - b[0]);
    if (splitsEither(na, ca, cb) || splitsEither(nb, ca, cb)) return false;
    if (k == 2) {
        const dvec3 e = a[sharedA[1]];  // the shared edge, from the origin
        return !(splitsEither(glm::cross(na, e), ca, cb) || splitsEither(glm::cross(nb, e), ca, cb));
    }
    // The planes through the corner that hold an edge of each (the cones' faces), and the
    // in-plane normals of the edges; then sums of two of them (unit length), since two faces
    // that share a corner and lie in one plane, 180 degrees apart, are split only by a plane
    // strictly between their edges' normals.
    dvec3 axes[14];
    int n = 0;
    for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j) axes[n++] = glm::cross(ua[i], wb[j]);
    for (int i = 0; i < 2; ++i)
        axes[n++] = glm::cross(na, ua[i]), axes[n++] = glm::cross(na, wb[i]), axes[n++] = glm::cross(nb, ua[i]),
        axes[n++] = glm::cross(nb, wb[i]);
    for (int i = 0; i < n; ++i)
        if (splitsEither(axes[i], ca, cb)) return false;
    for (int i = 0; i < n; ++i) {
        const double li = glm::length(axes[i]);
        if (!(li > 0)) continue;
        for (int j = i + 1; j < n; ++j) {
            const double lj = glm::length(axes[j]);
            if (!(lj > 0)) continue;
            if (splitsEither(axes[i] / li + axes[j] / lj, ca, cb) || splitsEither(axes[i] / li - axes[j] / lj, ca, cb)) return false;
        }
    }
    return true;
}

SolidParts solidParts(const std::vector<SolidTriangle>& triangles) {
    SolidParts result;
    // Edges as corner pairs, sorted so that the two sides of each edge are neighbours: 4 bytes
    // per edge and per triangle besides the triangles, then union-find over the triangles.
    const uint32_t n = uint32_t(triangles.size());
    auto corner = [&](uint32_t edge, int end) {
        const glm::vec3& v = triangles[edge / 3].v[(edge % 3 + uint32_t(end)) % 3];
        return std::array<float, 3>{v.x + 0.0f, v.y + 0.0f, v.z + 0.0f};  // -0 and +0 are one point
    };
    auto ends = [&](uint32_t edge) {
        auto a = corner(edge, 0), b = corner(edge, 1);
        return a < b ? std::pair(a, b) : std::pair(b, a);
    };
    std::vector<uint32_t> edges(size_t(n) * 3);
    for (uint32_t e = 0; e < edges.size(); ++e) edges[e] = e;
    std::sort(edges.begin(), edges.end(), [&](uint32_t x, uint32_t y) { return ends(x) < ends(y) || (ends(x) == ends(y) && x < y); });
    std::vector<uint32_t> parent(n);
    for (uint32_t t = 0; t < n; ++t) parent[t] = t;
    auto root = [&](uint32_t t) {
        while (parent[t] != t) t = parent[t] = parent[parent[t]];
        return t;
    };
    for (size_t i = 1, run = 1; i < edges.size(); ++i) {
        const bool same = ends(edges[i]) == ends(edges[i - 1]);
        run = same ? run + 1 : 1;
        result.sharedEdge = result.sharedEdge || run > 2;
        if (same) parent[root(edges[i] / 3)] = root(edges[i - 1] / 3);
    }
    releaseStorage(edges);
    // Each part's signed volume, kept at its root triangle.
    std::vector<OutwardVolume> volume(n);
    for (uint32_t t = 0; t < n; ++t) volume[root(t)].add(Triangle{{triangles[t].v[0], triangles[t].v[1], triangles[t].v[2]}, 0});
    for (uint32_t t = 0; t < n; ++t)
        if (root(t) == t && !volume[t].outward()) result.inward = true;
    return result;
}

bool solidMayCrossItself(std::vector<SolidTriangle>& triangles) {
    std::erase_if(triangles, [](const SolidTriangle& t) {
        const dvec3 n = glm::cross(dvec3(t.v[1]) - dvec3(t.v[0]), dvec3(t.v[2]) - dvec3(t.v[0]));
        return !(norm1(n) > 0);  // collinear corners (or NaN): no area, nothing to cross
    });
    if (triangles.size() < 2) return false;
    glm::vec3 lo(INFINITY), hi(-INFINITY);
    for (const SolidTriangle& t : triangles)
        for (const glm::vec3& v : t.v) lo = glm::min(lo, v), hi = glm::max(hi, v);
    const glm::vec3 extent = hi - lo;
    const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
    auto low = [](const SolidTriangle& t, int c) { return std::min({t.v[0][c], t.v[1][c], t.v[2][c]}); };
    auto high = [](const SolidTriangle& t, int c) { return std::max({t.v[0][c], t.v[1][c], t.v[2][c]}); };
    std::sort(triangles.begin(), triangles.end(), [&](const SolidTriangle& x, const SolidTriangle& y) { return low(x, axis) < low(y, axis); });
    for (size_t i = 0; i < triangles.size(); ++i) {
        const SolidTriangle& t = triangles[i];
        const float end = high(t, axis);
        for (size_t j = i + 1; j < triangles.size() && low(triangles[j], axis) <= end; ++j) {
            const SolidTriangle& u = triangles[j];
            bool overlap = true;  // boxes that touch count: touching triangles are tested
            for (int c = 0; c < 3 && overlap; ++c) overlap = c == axis || (low(t, c) <= high(u, c) && low(u, c) <= high(t, c));
            if (overlap && trianglesMayCross(t, u)) return true;
        }
    }
    return false;
}

}  // namespace penumbra
