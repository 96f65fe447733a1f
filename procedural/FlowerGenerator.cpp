#include "procedural/FlowerGenerator.h"

#include "stream/AlphaTable.h"

#include "procedural/IndexedSource.h"
#include "stream/util/CheckedMath.h"
#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"
#include "stream/util/Random.h"

#include <cmath>

namespace penumbra {
namespace {

constexpr double kPi = 3.14159265358979323846;

class FlowerSource final : public ItemSource {
public:
    explicit FlowerSource(const FlowerParams& p)
        : ItemSource("flowers", p.placement.count, flowerTriangleCount(p)), p_(p),
          flags_(p.alphaMatte ? uint32_t(kTriangleAlphaMatte) : 0u) {
        // Angles that are the same for every flower, so each flower needs only a few sincos.
        for (int k = 0; k <= p.stemSides; ++k) {
            const double a = 2 * kPi * k / p.stemSides;
            ring_[k] = glm::dvec3(std::cos(a), 0, std::sin(a));
        }
        for (int k = 0; k < p.petals; ++k) {
            const double a = 2 * kPi * k / p.petals;
            fan_[k] = glm::dvec2(std::cos(a), std::sin(a));
        }
    }

    uint64_t residentBytes() const override { return p_.placement.residentBytes(); }
    size_t read(std::span<Triangle> out) override {
        p_.placement.prepare();
        return ItemSource::read(out);
    }

protected:
    void item(uint64_t flower, Triangle* out) const override {
        Rng rng(hashIndex(p_.seed, flower));
        double x, z;
        randomPoint(p_.placement.area, rng, x, z);
        const glm::dvec3 root(x, p_.placement.groundHeight(x, z), z);
        const double height = rng.uniform(p_.height.x, p_.height.y);
        const double lean = rng.uniform(0, 2 * kPi), reach = height * rng.uniform(p_.stemBend.x, p_.stemBend.y);
        const glm::dvec3 forward(std::cos(lean), 0, std::sin(lean));
        // The stem's centre line is the parabola root + up * height * s + forward * reach * s^2.
        auto centre = [&](double s) { return root + glm::dvec3(0, height * s, 0) + forward * (reach * s * s); };
        Triangle* t = out;
        auto emit = [&](const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, uint32_t alpha = 0) {
            *t++ = Triangle{{glm::vec3(a), glm::vec3(b), glm::vec3(c)}, alpha ? withAlphaId(flags_, alpha) : flags_};
        };

        // Stem: horizontal rings of stemSides vertices, tapering to 60% at the head.
        const int sides = p_.stemSides, segments = p_.stemSegments;
        for (int g = 0; g < segments; ++g) {
            const double s0 = double(g) / segments, s1 = double(g + 1) / segments;
            const glm::dvec3 c0 = centre(s0), c1 = centre(s1);
            const double r0 = p_.stemRadius * (1.0 - 0.4 * s0), r1 = p_.stemRadius * (1.0 - 0.4 * s1);
            for (int k = 0; k < sides; ++k) {
                const glm::dvec3 &d0 = ring_[k], &d1 = ring_[k + 1];
                emit(c0 + r0 * d0, c0 + r0 * d1, c1 + r1 * d1);
                emit(c0 + r0 * d0, c1 + r1 * d1, c1 + r1 * d0);
            }
        }

        // Petals: a fan of diamonds around the head, all rising at the same tilt.
        const glm::dvec3 head = centre(1.0);
        const double length = rng.uniform(p_.petalLength.x, p_.petalLength.y);
        const double tilt = rng.uniform(p_.petalTiltDeg.x, p_.petalTiltDeg.y) * kPi / 180.0;
        const double phase = rng.uniform(0, 2 * kPi), halfWidth = 0.5 * p_.petalWidth * length;
        const double cp = std::cos(phase), sp = std::sin(phase), ct = std::cos(tilt), st = std::sin(tilt);
        for (int k = 0; k < p_.petals; ++k) {
            // The fan's k-th direction turned by the flower's phase.
            const double ca = fan_[k].x * cp - fan_[k].y * sp, sa = fan_[k].y * cp + fan_[k].x * sp;
            const glm::dvec3 out(ca * ct, st, sa * ct), across(-sa, 0, ca);
            const glm::dvec3 tip = head + length * out, middle = head + 0.45 * length * out;
            // head, side, tip, other side: the canonical quad (0,0) (1,0) (1,1) (0,1).
            emit(head, middle + halfWidth * across, tip, p_.petalCutout ? uint32_t(kAlphaPetalLower) : 0u);
            emit(head, tip, middle - halfWidth * across, p_.petalCutout ? uint32_t(kAlphaPetalUpper) : 0u);
        }

        // Leaves: 3-triangle strips that leave the stem low down, rise, then droop.
        for (int q = 0; q < p_.leaves; ++q) {
            const double at = 0.1 + 0.35 * rng.uniform(), a = rng.uniform(0, 2 * kPi);
            const double len = rng.uniform(p_.leafLength.x, p_.leafLength.y);
            const glm::dvec3 base = centre(at), out(std::cos(a), 0, std::sin(a)), across(-std::sin(a), 0, std::cos(a));
            glm::dvec3 v[5];
            for (int j = 0; j < 5; ++j) {
                const double s = double(j < 1 ? 0 : j - 1) / 3.0;
                const double side = (j % 2 ? 0.5 : -0.5) * p_.leafWidth * (1.0 - s);
                v[j] = base + out * (len * s) + glm::dvec3(0, len * (0.8 * s - 0.6 * s * s), 0) + across * side;
            }
            emit(v[0], v[1], v[2]);
            emit(v[2], v[1], v[3]);
            emit(v[2], v[3], v[4]);
        }
    }

private:
    FlowerParams p_;
    uint32_t flags_;
    glm::dvec3 ring_[9];  // stem ring directions, stemSides + 1 of them (the last repeats the first)
    glm::dvec2 fan_[16];  // petal directions before the per-flower turn
};

void requireRange(const JsonParams& j, const char* key, const glm::dvec2& r, double lo, double hi, bool openLo) {
    if (!((openLo ? r.x > lo : r.x >= lo) && r.y <= hi))
        fail(j.where(key), "must lie in {}{}, {}], got [{}, {}]", openLo ? "(" : "[", lo, hi, r.x, r.y);
}

}  // namespace

uint32_t flowerTriangleCount(const FlowerParams& p) {
    return uint32_t(2 * p.stemSides * p.stemSegments + 2 * p.petals + 3 * p.leaves);
}

FlowerParams parseFlowerParams(const SourceRequest& request) {
    JsonParams j(request.params, request.file, request.path);
    FlowerParams p;
    p.stemSides = int(j.integer("stem_sides", p.stemSides, 3, 8));
    p.stemSegments = int(j.integer("stem_segments", p.stemSegments, 1, 4));
    p.petals = int(j.integer("petals", p.petals, 3, 16));
    p.leaves = int(j.integer("leaves", p.leaves, 0, 6));
    p.placement = parsePlacement(j, 1000, kMaxSceneTriangles / flowerTriangleCount(p));
    p.height = j.range("height", p.height);
    p.stemRadius = j.number("stem_radius", p.stemRadius);
    p.stemBend = j.range("stem_bend", p.stemBend);
    p.petalLength = j.range("petal_length", p.petalLength);
    p.petalWidth = j.number("petal_width", p.petalWidth);
    p.petalTiltDeg = j.range("petal_tilt_deg", p.petalTiltDeg);
    p.leafLength = j.range("leaf_length", p.leafLength);
    p.leafWidth = j.number("leaf_width", p.leafWidth);
    p.alphaMatte = j.boolean("alpha_matte", p.alphaMatte);
    p.petalCutout = j.boolean("petal_cutout", p.petalCutout);
    p.seed = j.seed("seed", p.seed);
    j.finish();
    requireRange(j, "height", p.height, 0, 1e6, true);
    requireRange(j, "stem_bend", p.stemBend, -4, 4, false);
    requireRange(j, "petal_length", p.petalLength, 0, 1e6, true);
    requireRange(j, "petal_tilt_deg", p.petalTiltDeg, -89, 89, false);
    requireRange(j, "leaf_length", p.leafLength, 0, 1e6, true);
    if (!(p.stemRadius > 0 && p.stemRadius <= 1e6)) fail(j.where("stem_radius"), "must be in (0, 1e6], got {}", p.stemRadius);
    if (!(p.petalWidth > 0 && p.petalWidth <= 4)) fail(j.where("petal_width"), "must be in (0, 4], got {}", p.petalWidth);
    if (!(p.leafWidth > 0 && p.leafWidth <= 1e6)) fail(j.where("leaf_width"), "must be in (0, 1e6], got {}", p.leafWidth);
    return p;
}

TriangleSourcePtr makeFlowerSource(const FlowerParams& params) { return std::make_unique<FlowerSource>(params); }

}  // namespace penumbra
