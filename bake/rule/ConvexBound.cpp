#include "bake/rule/ConvexBound.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace penumbra {
namespace {

struct P2 {
    double x, y;
};

double cross2(P2 o, P2 a, P2 b) { return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x); }

double polygonArea(const std::vector<P2>& poly) {
    double a = 0.0;
    for (size_t i = 0; i < poly.size(); ++i) {
        const P2& p = poly[i];
        const P2& q = poly[(i + 1) % poly.size()];
        a += p.x * q.y - q.x * p.y;
    }
    return 0.5 * std::abs(a);
}

/// Andrew's monotone chain; counter-clockwise, collinear points dropped.
std::vector<P2> convexHull(std::vector<P2> pts) {
    std::sort(pts.begin(), pts.end(), [](P2 a, P2 b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
    if (pts.size() < 3) return pts;
    std::vector<P2> hull(2 * pts.size());
    size_t k = 0;
    for (size_t i = 0; i < pts.size(); ++i) {
        while (k >= 2 && cross2(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
        hull[k++] = pts[i];
    }
    for (size_t i = pts.size() - 1, t = k + 1; i-- > 0;) {
        while (k >= t && cross2(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
        hull[k++] = pts[i];
    }
    hull.resize(k - 1);
    return hull;
}

/// Keeps the part of a convex polygon where dot(dir, p) lies in [lo, hi].
std::vector<P2> clipSlab(const std::vector<P2>& poly, P2 dir, double lo, double hi) {
    auto clip = [](const std::vector<P2>& in, P2 d, double bound, double sign) {
        std::vector<P2> out;
        for (size_t i = 0; i < in.size(); ++i) {
            P2 a = in[i], b = in[(i + 1) % in.size()];
            double fa = sign * (bound - (d.x * a.x + d.y * a.y));
            double fb = sign * (bound - (d.x * b.x + d.y * b.y));
            if (fa >= 0) out.push_back(a);
            if ((fa >= 0) != (fb >= 0)) {
                double t = fa / (fa - fb);
                out.push_back({a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)});
            }
        }
        return out;
    };
    return clip(clip(poly, dir, hi, 1.0), dir, lo, -1.0);
}

bool containsAll(const std::vector<P2>& polyCcw, const std::vector<P2>& pts) {
    for (size_t i = 0; i < polyCcw.size(); ++i) {
        P2 a = polyCcw[i], b = polyCcw[(i + 1) % polyCcw.size()];
        for (const P2& p : pts)
            if (cross2(a, b, p) < 0) return false;
    }
    return true;
}

}  // namespace

ConvexBound boundPlanarPoints(std::span<const glm::dvec3> points, const glm::dvec3& origin,
                              const glm::dvec3& u, const glm::dvec3& v, const glm::dvec3& n,
                              std::span<const glm::dvec3> extraCandidate) {
    std::vector<P2> pts;
    pts.reserve(points.size());
    double hLo = std::numeric_limits<double>::infinity(), hHi = -hLo;
    double xLo = hLo, xHi = -hLo, yLo = hLo, yHi = -hLo, dLo = hLo, dHi = -hLo, eLo = hLo, eHi = -hLo;
    const double s = std::sqrt(0.5);
    for (const glm::dvec3& p : points) {
        glm::dvec3 q = p - origin;
        P2 c{glm::dot(q, u), glm::dot(q, v)};
        pts.push_back(c);
        double h = glm::dot(q, n);
        hLo = std::min(hLo, h), hHi = std::max(hHi, h);
        xLo = std::min(xLo, c.x), xHi = std::max(xHi, c.x);
        yLo = std::min(yLo, c.y), yHi = std::max(yHi, c.y);
        double d = s * (c.x + c.y), e = s * (c.x - c.y);
        dLo = std::min(dLo, d), dHi = std::max(dHi, d);
        eLo = std::min(eLo, e), eHi = std::max(eHi, e);
    }

    std::vector<P2> best = {{xLo, yLo}, {xHi, yLo}, {xHi, yHi}, {xLo, yHi}};
    auto consider = [&](const std::vector<P2>& candidate) {
        if (candidate.size() >= 3 && polygonArea(candidate) < polygonArea(best)) best = candidate;
    };
    // Octagon: it only pays when it is clearly smaller (extra planes cost time per triangle).
    std::vector<P2> octagon = clipSlab(clipSlab(best, {s, s}, dLo, dHi), {s, -s}, eLo, eHi);
    if (octagon.size() >= 3 && polygonArea(octagon) < 0.9 * polygonArea(best)) best = octagon;
    std::vector<P2> hull = convexHull(pts);
    if (hull.size() >= 3 && hull.size() <= 8) consider(hull);
    if (extraCandidate.size() >= 3) {
        std::vector<P2> extra;
        for (const glm::dvec3& p : extraCandidate) extra.push_back({glm::dot(p - origin, u), glm::dot(p - origin, v)});
        extra = convexHull(extra);
        if (extra.size() >= 3 && containsAll(extra, pts)) consider(extra);
    }

    ConvexBound bound;
    int m = static_cast<int>(best.size());
    auto layer = [&](double h) {
        for (const P2& p : best) bound.vertices.push_back(origin + p.x * u + p.y * v + h * n);
    };
    layer(hLo);
    for (int i = 0; i < m; ++i) bound.edges.push_back({i, (i + 1) % m});
    if (hHi > hLo) {  // float rounding lifted samples off the plane: bound them with a thin prism
        layer(hHi);
        for (int i = 0; i < m; ++i) {
            bound.edges.push_back({m + i, m + (i + 1) % m});
            bound.edges.push_back({i, m + i});
        }
    }
    return bound;
}

ConvexBound boundPoints3D(std::span<const glm::dvec3> points) {
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (const glm::dvec3& p : points) lo = glm::min(lo, p), hi = glm::max(hi, p);
    ConvexBound bound;
    for (int i = 0; i < 8; ++i)
        bound.vertices.push_back({(i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z});
    for (int i = 0; i < 8; ++i)
        for (int bit : {1, 2, 4})
            if (!(i & bit)) bound.edges.push_back({i, i | bit});
    return bound;
}

}  // namespace penumbra
