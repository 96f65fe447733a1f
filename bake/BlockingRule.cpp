#include "bake/BlockingRule.h"

namespace penumbra {

bool isTie(const glm::dvec3& l, const glm::dvec3& r, const BlockerTriangle& t, double epsilon,
           double tolerance) {
    if (!t.valid) return false;
    double eps = receiverEpsilon(r, epsilon);
    double lenRL = glm::length(l - r);
    double scale = std::max({1.0, glm::length(r), glm::length(l)});
    double sl = t.plane.eval(l);
    double dr = t.plane.eval(r);
    // Sample or receiver (within the epsilon band) on T's plane: the two rules for "near the
    // receiver" (perpendicular distance here, distance along the ray elsewhere) disagree here.
    if (std::abs(sl) <= tolerance * scale) return true;
    if (std::abs(dr) <= eps * (1.0 + tolerance) + tolerance * scale) return true;
    // Does the segment cross T's plane at all? If not, only the band above can be a tie.
    if ((sl > 0.0) == (dr > 0.0)) return false;
    // Segment passes within roundoff of one of T's edges: inclusive versus exclusive edge tests.
    for (int e = 0; e < 3; ++e) {
        const glm::dvec3& a = t.v[e];
        const glm::dvec3& b = t.v[(e + 1) % 3];
        glm::dvec3 n = glm::cross(a - l, b - l);
        double len = glm::length(n);
        if (len == 0.0) return true;
        if (std::abs(glm::dot(n / len, r - l)) <= tolerance * lenRL) return true;
    }
    return false;
}

}  // namespace penumbra
