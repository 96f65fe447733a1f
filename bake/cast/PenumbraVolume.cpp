#include "bake/cast/PenumbraVolume.h"

#include "bake/cast/PenumbraVolumeBuilder.h"

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace volume_detail {
namespace {

/// Adds the plane through @p anchor (a vertex of T) with normal ±@p normal if it separates T
/// (positive side) from the bound. Every value is taken relative to the anchor, and a bound
/// vertex b of weight w as b - w anchor, so a far or infinite light costs no precision.
/// Candidates are judged unnormalised, comparing squares against the tolerance, because most
/// are rejected; only accepted planes are normalised. The points that define the candidate
/// (triangle vertices @p triOn, a bit set, and bound vertices @p boundOnA / @p boundOnB) lie
/// on it up to roundoff far below the tolerance, so they are not evaluated: that halves the
/// work per candidate.
void tryPlane(Builder& b, const glm::dvec3& normal, const glm::dvec3& anchor, unsigned triOn, size_t boundOnA,
              size_t boundOnB) {
    const double nn = glm::dot(normal, normal);
    if (!(nn > 0.0) || !std::isfinite(nn)) return;
    const double tol2 = b.tolerancePrefix() * nn;  // (tolerance * |n|)^2
    // Orientation from the triangle vertex farthest from the plane; then every vertex must
    // agree. Most candidates fail on an early vertex, so bail out as soon as one does.
    double e[3] = {0.0, 0.0, 0.0}, far = 0.0;
    for (int i = 0; i < 3; ++i) {
        if (triOn >> i & 1u) continue;
        e[i] = glm::dot(normal, b.t.v[i] - anchor);
        if (std::abs(e[i]) > std::abs(far)) far = e[i];
    }
    const double s = far < 0.0 ? -1.0 : 1.0;  // triangle on the positive side
    for (double v : e)
        if (s * v < 0.0 && v * v > tol2) return;
    const double w = b.bound.w;
    for (size_t i = 0; i < b.bound.vertices.size(); ++i) {
        if (i == boundOnA || i == boundOnB) continue;
        const double x = s * glm::dot(normal, b.bound.vertices[i] - w * anchor);
        // A direction's value is on the scale of the direction (about 1), not of the scene.
        if (x > 0.0 && x * x > b.boundTolerance(i, tol2)) return;
    }
    b.accept(normal, nn, s, anchor);
}

}  // namespace

void addCandidatesScalar(Builder& b) {
    const ConvexBound& bound = b.bound;
    const BlockerTriangle& t = b.t;
    const double w = bound.w;
    for (int e = 0; e < 3; ++e) {
        const glm::dvec3& a = t.v[e];
        const glm::dvec3& c = t.v[(e + 1) % 3];
        const unsigned on = (1u << e) | (1u << (e + 1) % 3);
        for (size_t i = 0; i < bound.vertices.size() && !b.culled; ++i)
            tryPlane(b, glm::cross(c - a, bound.vertices[i] - w * a), a, on, i, kNone);
    }
    // Through an edge (p, q) of the bound and a vertex v of T: normal (p - w v) x (q - p), which
    // needs no difference of two far, nearly parallel vectors; for directions, p x q.
    for (const auto& edge : bound.edges) {
        const glm::dvec3& p = bound.vertices[edge[0]];
        const glm::dvec3& q = bound.vertices[edge[1]];
        const glm::dvec3 along = q - p;
        for (int i = 0; i < 3 && !b.culled; ++i)
            tryPlane(b, glm::cross(p - w * t.v[i], along), t.v[i], 1u << i, edge[0], edge[1]);
    }
}

}  // namespace volume_detail

using namespace volume_detail;

PenumbraVolume makePenumbraVolume(const ConvexBound& bound, const BlockerTriangle& t) {
    PenumbraVolume volume;
    buildPenumbraVolume(bound, t, volume);
    return volume;
}

namespace {

double volumeScale(const ConvexBound& bound, const BlockerTriangle& t) {
    double scale = 1.0;
    for (const glm::dvec3& v : bound.vertices) scale = std::max({scale, std::abs(v.x), std::abs(v.y), std::abs(v.z)});
    for (const glm::dvec3& v : t.v) scale = std::max({scale, std::abs(v.x), std::abs(v.y), std::abs(v.z)});
    return scale;
}

/// The cap of the volume (T's plane, oriented away from the bound), or false when T's plane cuts
/// the bound. A bound vertex's side is taken relative to T (BlockerTriangle::side()).
bool capPlane(const ConvexBound& bound, const BlockerTriangle& t, double scale, Plane& cap) {
    double lo = INFINITY, hi = -INFINITY;
    for (const glm::dvec3& v : bound.vertices) {
        double e = t.side(v, bound.w);
        lo = std::min(lo, e), hi = std::max(hi, e);
    }
    const double tol = kAccept * (bound.directional() ? 1.0 : scale);
    if (hi < -tol) cap = t.plane;
    else if (lo > tol) cap = t.plane.flipped();
    else return false;
    return true;
}

}  // namespace

bool buildPenumbraVolume(const ConvexBound& bound, const BlockerTriangle& t, PenumbraVolume& volume, const Box* cull,
                         SimdLevel level) {
    volume.count = 0, volume.frontCulled = false;
    volume.nx[0] = volume.ny[0] = volume.nz[0] = volume.d[0] = 0.0;  // the slot after the last
    Builder b{bound, t, volume, volumeScale(bound, t), cull};

    // Cap first: it is the plane most likely to reject a box, and order is the test order.
    Plane cap;
    if (capPlane(bound, t, b.scale, cap)) b.add(cap);

    double boundTolerance2[kMaxBoundVertices];  // filled for directions only (kept unzeroed)
    if (bound.vertices.size() > kMaxBoundVertices) return !b.culled;  // (never: at most 16) no planes: all space
    if (bound.directional()) {
        for (size_t i = 0; i < bound.vertices.size(); ++i) {
            const glm::dvec3& v = bound.vertices[i];
            const double m = std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}) / b.scale;
            boundTolerance2[i] = m * m;
        }
        b.boundTolerance2 = boundTolerance2;
    }
    if (b.culled) return false;
    if (level == SimdLevel::Avx2) addCandidatesAvx2(b);
    else addCandidatesScalar(b);
    return !b.culled;
}

}  // namespace penumbra
