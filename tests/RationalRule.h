#pragma once
// The blocking rule (bake/BlockingRule.h) evaluated in exact rational arithmetic on the float
// inputs: a test-only oracle, independent of every double-precision evaluation in the project.
// Floats are dyadic rationals, and every quantity of the rule is a polynomial in them, so
// boost::multiprecision's cpp_rational decides each relation exactly; the only irrational step
// (the unit normal of the band test) is avoided by comparing squares.

#include "stream/Triangle.h"

#include <boost/multiprecision/cpp_int.hpp>
#include <glm/vec3.hpp>

#include <algorithm>
#include <cmath>

namespace penumbra::test {

using Rational = boost::multiprecision::cpp_rational;

struct RationalVec {
    Rational x, y, z;
    explicit RationalVec(const glm::dvec3& v) : x(v.x), y(v.y), z(v.z) {}
    RationalVec(Rational a, Rational b, Rational c) : x(std::move(a)), y(std::move(b)), z(std::move(c)) {}
};

inline RationalVec operator-(const RationalVec& a, const RationalVec& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline RationalVec operator*(const Rational& s, const RationalVec& a) { return {s * a.x, s * a.y, s * a.z}; }
inline Rational dot(const RationalVec& a, const RationalVec& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline RationalVec cross(const RationalVec& a, const RationalVec& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

/// @brief The rule's exact decision for sample (@p l, @p w) (w = 1 point, 0 direction), receiver
/// @p r and triangle @p t, with eps(r) = relative * max(|r|_inf, length) (both doubles, exact).
inline bool exactlyBlocks(const glm::dvec3& l, double w, const glm::dvec3& r, const Triangle& t, double relative,
                          double length) {
    const RationalVec v0(glm::dvec3(t.v[0])), v1(glm::dvec3(t.v[1])), v2(glm::dvec3(t.v[2]));
    const RationalVec L(l), R(r);
    const Rational W(w);
    const RationalVec n = cross(v1 - v0, v2 - v0);
    const Rational nn = dot(n, n);
    if (nn == 0) return false;
    const Rational sl = dot(n, L - W * v0);
    if (sl == 0) return false;
    const Rational s = sl > 0 ? 1 : -1;
    const RationalVec* v[3] = {&v0, &v1, &v2};
    for (int e = 0; e < 3; ++e) {
        const RationalVec& a = *v[e];
        const RationalVec& b = *v[(e + 1) % 3];
        if (s * dot(cross(L - W * a, b - a), R - a) < 0) return false;
    }
    // -s n.(r - v0) / |n| > eps  <=>  D > 0 and D^2 > eps^2 |n|^2, with D = -s n.(r - v0).
    const Rational d = -s * dot(n, R - v0);
    const Rational eps = Rational(relative) * Rational(std::max({length, std::abs(r.x), std::abs(r.y), std::abs(r.z)}));
    return d > 0 && d * d > eps * eps * nn;
}

}  // namespace penumbra::test
