#include "bake/PenumbraVolume.h"

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

// Relative tolerances. kAccept decides whether a candidate plane separates (defining vertices
// evaluate to roundoff, not zero); kMargin pushes accepted planes outward. kMargin >> kAccept
// keeps the volume conservative for receivers up to ~1000x farther from the blocker than the
// blocker is from the light (see docs/design.md, "Conservativeness").
constexpr double kAccept = 1e-12;
constexpr double kMargin = 1e-9;

struct Builder {
    const ConvexBound& bound;
    const BlockerTriangle& t;
    PenumbraVolume volume;
    double scale = 1.0;

    void tryPlane(const glm::dvec3& normal, const glm::dvec3& through) {
        double len = glm::length(normal);
        if (!(len > 0.0) || !std::isfinite(len)) return;
        Plane p = Plane::through(normal / len, through);
        const double tol = kAccept * scale;
        // Orientation from the triangle vertex farthest from the plane; then every vertex must
        // agree. Most candidates fail on an early vertex, so bail out as soon as one does.
        double far = 0.0;
        for (const glm::dvec3& v : t.v) {
            double e = p.eval(v);
            if (std::abs(e) > std::abs(far)) far = e;
        }
        if (far < 0.0) p = p.flipped();  // triangle on the positive side
        for (const glm::dvec3& v : t.v)
            if (p.eval(v) < -tol) return;
        for (const glm::dvec3& v : bound.vertices)
            if (p.eval(v) > tol) return;
        add(p);
    }

    void add(Plane p) {
        p.d += kMargin * scale;
        for (int i = 0; i < volume.count; ++i) {
            const Plane& q = volume.planes[i];
            if (glm::dot(q.n, p.n) > 1.0 - 1e-12 && std::abs(q.d - p.d) <= kAccept * scale) return;
        }
        if (volume.count < PenumbraVolume::kMaxPlanes) volume.planes[volume.count++] = p;
        // Dropping a plane beyond the limit only enlarges the volume: still conservative.
    }
};

}  // namespace

PenumbraVolume makePenumbraVolume(const ConvexBound& bound, const BlockerTriangle& t) {
    Builder b{bound, t, {}};
    for (const glm::dvec3& v : bound.vertices)
        b.scale = std::max({b.scale, std::abs(v.x), std::abs(v.y), std::abs(v.z)});
    for (const glm::dvec3& v : t.v) b.scale = std::max({b.scale, std::abs(v.x), std::abs(v.y), std::abs(v.z)});

    // Cap first: it is the plane most likely to reject a box, and order is the test order.
    double lo = INFINITY, hi = -INFINITY;
    for (const glm::dvec3& v : bound.vertices) {
        double e = t.plane.eval(v);
        lo = std::min(lo, e), hi = std::max(hi, e);
    }
    double tol = kAccept * b.scale;
    if (hi < -tol) b.add(t.plane);
    else if (lo > tol) b.add(t.plane.flipped());

    for (int e = 0; e < 3; ++e) {
        const glm::dvec3& a = t.v[e];
        const glm::dvec3& c = t.v[(e + 1) % 3];
        for (const glm::dvec3& p : bound.vertices) b.tryPlane(glm::cross(c - a, p - a), a);
    }
    for (const auto& edge : bound.edges) {
        const glm::dvec3& a = bound.vertices[edge[0]];
        const glm::dvec3& c = bound.vertices[edge[1]];
        for (const glm::dvec3& p : t.v) b.tryPlane(glm::cross(c - a, p - a), a);
    }
    return b.volume;
}

}  // namespace penumbra
