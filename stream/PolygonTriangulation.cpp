#include "stream/PolygonTriangulation.h"

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include <cmath>

namespace penumbra {
namespace {

/// The polygon projected on the plane of its Newell normal's largest axis, oriented so that the
/// polygon winds counter-clockwise there (a positive turn is a convex corner).
void project(std::span<const glm::vec3> c, std::vector<glm::dvec2>& p) {
    glm::dvec3 n(0.0);
    for (size_t i = 0, j = c.size() - 1; i < c.size(); j = i++) {
        const glm::dvec3 a(c[j]), b(c[i]);
        n += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    }
    const glm::dvec3 m = glm::abs(n);
    const int axis = m.x >= m.y && m.x >= m.z ? 0 : m.y >= m.z ? 1 : 2;
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;  // (u, v, axis) is right-handed
    const double flip = n[axis] < 0.0 ? -1.0 : 1.0;
    p.resize(c.size());
    for (size_t i = 0; i < c.size(); ++i) p[i] = {double(c[i][u]), flip * double(c[i][v])};
}

double turn(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
    return (b.x - a.x) * (c.y - b.y) - (b.y - a.y) * (c.x - b.x);
}

/// Whether @p q lies inside or on triangle (a, b, c), wound counter-clockwise.
bool inside(const glm::dvec2& q, const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
    return turn(a, b, q) >= 0.0 && turn(b, c, q) >= 0.0 && turn(c, a, q) >= 0.0;
}

bool convex(const std::vector<glm::dvec2>& p) {
    for (size_t i = 0; i < p.size(); ++i)
        if (turn(p[(i + p.size() - 1) % p.size()], p[i], p[(i + 1) % p.size()]) < 0.0) return false;
    return true;
}

/// Ear tests' corner visits one face may take (about a second): ear clipping is quadratic in the
/// corners, cubic at worst, and an OBJ face may have millions of them.
constexpr uint64_t kEarClipWork = uint64_t(1) << 28;

/// Ear clipping over the ring @p ring of indices into @p p. An ear is a convex corner whose
/// triangle holds no other reflex corner (only reflex corners can lie in it); a corner at the
/// same point as one of the ear's does not count, so that polygons touching themselves clip.
void clipEars(const std::vector<glm::dvec2>& p, std::vector<uint32_t> ring, std::vector<std::array<uint32_t, 3>>& out) {
    auto at = [&](size_t k) { return p[ring[k % ring.size()]]; };
    size_t k = 0, sinceEar = 0;
    uint64_t work = 0;  // corners visited by ear tests, against kEarClipWork
    while (ring.size() > 3) {
        if (work > kEarClipWork) {  // the rest as a fan from the current corner: n - 2 all the same
            for (size_t i = 1; i + 1 < ring.size(); ++i) out.push_back({ring[k], ring[(k + i) % ring.size()], ring[(k + i + 1) % ring.size()]});
            return;
        }
        work += ring.size();
        const size_t n = ring.size(), prev = (k + n - 1) % n, next = (k + 1) % n;
        const glm::dvec2 a = at(prev), b = at(k), c = at(next);
        bool ear = turn(a, b, c) > 0.0;
        for (size_t j = 0; ear && j < n; ++j) {
            if (j == prev || j == k || j == next) continue;
            const glm::dvec2 q = at(j);
            if (q == a || q == b || q == c) continue;
            ear = !(turn(at(j + n - 1), q, at(j + 1)) <= 0.0 && inside(q, a, b, c));
        }
        // No ear in a whole round: the polygon crosses itself or is degenerate. Clip the corner
        // anyway where it is convex (or, failing that, any corner) so the count stays n - 2.
        if (!ear && sinceEar >= n) ear = turn(a, b, c) > 0.0 || sinceEar >= 2 * n;
        if (!ear) {
            k = next, ++sinceEar;
            continue;
        }
        out.push_back({ring[prev], ring[k], ring[next]});
        ring.erase(ring.begin() + std::ptrdiff_t(k));
        k = prev < k ? prev : prev - 1, sinceEar = 0;
    }
    out.push_back({ring[0], ring[1], ring[2]});
}

}  // namespace

void triangulatePolygon(std::span<const glm::vec3> corners, std::vector<std::array<uint32_t, 3>>& out) {
    out.clear();
    const uint32_t n = uint32_t(corners.size());
    if (n < 3) return;
    if (n == 3) {
        out.push_back({0, 1, 2});
        return;
    }
    thread_local std::vector<glm::dvec2> p;  // a face at a time: no allocation per quad of a large file
    project(corners, p);
    if (convex(p)) {
        for (uint32_t k = 1; k + 1 < n; ++k) out.push_back({0, k, k + 1});
        return;
    }
    std::vector<uint32_t> ring(n);
    for (uint32_t i = 0; i < n; ++i) ring[i] = i;
    clipEars(p, std::move(ring), out);
}

}  // namespace penumbra
