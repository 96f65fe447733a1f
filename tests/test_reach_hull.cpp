// The reach hull: every segment between the two balls lies inside it, and its distance is not an
// over-estimate (a blocker it culls really misses every segment).

#include "bake/rule/ReachHull.h"
#include "stream/Random.h"

#include <catch2/catch.hpp>
#include <glm/geometric.hpp>

#include <cmath>

using namespace penumbra;

namespace {

glm::dvec3 inBall(Rng& rng, const Ball& b) {
    for (;;) {
        glm::dvec3 d(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
        if (glm::dot(d, d) <= 1.0) return b.center + d * b.radius;
    }
}

}  // namespace

TEST_CASE("points of segments between the balls are inside the reach hull", "[hpc][reach]") {
    Rng rng(3);
    for (int trial = 0; trial < 50; ++trial) {
        Ball a{{rng.uniform(-5, 5), rng.uniform(3, 8), rng.uniform(-5, 5)}, rng.uniform(0.1, 3)};
        Ball b{{rng.uniform(-5, 5), rng.uniform(-2, 2), rng.uniform(-5, 5)}, rng.uniform(0.1, 6)};
        if (trial % 10 == 0) b = Ball{a.center, a.radius * 2};  // one ball inside the other
        ReachHull hull(a, b);
        for (int i = 0; i < 200; ++i) {
            glm::dvec3 p = inBall(rng, a), q = inBall(rng, b);
            glm::dvec3 s = p + rng.uniform() * (q - p);
            REQUIRE(hull.distance(s) <= 1e-9);
            REQUIRE_FALSE(hull.misses(Ball{s, 0.0}));
        }
    }
}

TEST_CASE("the reach hull's distance never exceeds the distance to a segment between the balls", "[hpc][reach]") {
    Rng rng(5);
    Ball a{{0, 5, 0}, 1.4}, b{{0, 0, 0}, 5.7};
    ReachHull hull(a, b);
    uint64_t outside = 0;
    for (int i = 0; i < 2000; ++i) {
        glm::dvec3 x(rng.uniform(-10, 10), rng.uniform(-3, 10), rng.uniform(-10, 10));
        const double d = hull.distance(x);
        if (d <= 0) continue;
        ++outside;
        // Any point of the hull is at least d away (sampled: segment points between the balls).
        for (int k = 0; k < 200; ++k) {
            glm::dvec3 p = inBall(rng, a), q = inBall(rng, b), s = p + rng.uniform() * (q - p);
            REQUIRE(glm::length(x - s) >= d - 1e-9);
        }
    }
    CHECK(outside > 200);
    // A blocker beside the light, as in the bench's root-cull case, is culled.
    CHECK(hull.misses(Ball{{3.5, 4.7, 3.5}, 0.2}));
    // One between the light and the floor is not.
    CHECK_FALSE(hull.misses(Ball{{0.5, 2.5, 0.5}, 0.2}));
}
