#include "procedural/GrassGenerator.h"

#include "procedural/IndexedSource.h"
#include "stream/util/CheckedMath.h"
#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"
#include "stream/util/Random.h"

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

constexpr int kMaxSegments = 7;
constexpr double kDegree = 3.14159265358979323846 / 180.0;
constexpr uint64_t kClumpStream = 0x636C756D70ull;  // "clump": keeps the mask independent of placement

/// @brief Stratified placement: the area is cut into about count / kBladesPerTile equal tiles, and
/// consecutive blades share a tile (blade b goes to tile floor(b * tiles / count), so every tile
/// gets the same number of blades, give or take one). Coverage is more even than plain uniform
/// sampling, and a chunk of blades touches only a few terrain cells, which keeps the height
/// look-ups in cache. A pure function of the parameters: nothing is stored per tile.
struct Strata {
    static constexpr uint64_t kBladesPerTile = 64;
    Area area;
    uint64_t count = 0, tiles = 1, columns = 1;
    double tileX = 0, tileZ = 0;

    explicit Strata(const Placement& p) : area(p.area), count(p.count) {
        const uint64_t wanted = std::max<uint64_t>(1, count / kBladesPerTile);
        // Tiles about square: columns / rows follows the area's aspect ratio.
        const double aspect = area.sizeX() / area.sizeZ();
        columns = uint64_t(std::clamp(std::round(std::sqrt(double(wanted) * aspect)), 1.0, double(wanted)));
        const uint64_t rows = std::max<uint64_t>(1, wanted / columns);
        tiles = columns * rows;
        tileX = area.sizeX() / double(columns), tileZ = area.sizeZ() / double(rows);
    }

    /// A uniform point of blade @p blade's tile (two draws).
    void point(uint64_t blade, Rng& rng, double& x, double& z) const {
        const uint64_t tile = count ? uint64_t((unsigned __int128)blade * tiles / count) : 0;
        x = area.x0 + tileX * (double(tile % columns) + rng.uniform());
        z = area.z0 + tileZ * (double(tile / columns) + rng.uniform());
    }
};

/// Draws blade @p blade's root position (and the clump shortening factor) from @p rng; consumes
/// a variable but deterministic number of draws. The first candidate lies in the blade's own
/// tile; further ones (only drawn when the first is bare) anywhere in the area, so that blades
/// of a bare tile move into the clumps instead of piling up as stragglers.
/// @param mask the clump field, or null when clumps are off
float drawRoot(const GrassParams& p, const Strata& strata, const Fbm* mask, uint64_t blade, Rng& rng, double& x, double& z) {
    strata.point(blade, rng, x, z);
    if (!mask) return 1.0f;
    const ClumpParams& c = p.clump;
    double best = (*mask)(x, z), bx = x, bz = z;
    for (int t = 1; t < c.tries && best < c.threshold; ++t) {
        randomPoint(p.placement.area, rng, x, z);
        double m = (*mask)(x, z);
        if (m > best) best = m, bx = x, bz = z;
    }
    x = bx, z = bz;
    // Shorter blades near a clump's edge (and on the rare stragglers in bare patches).
    double t = std::clamp((best - c.threshold) / c.edge, 0.0, 1.0);
    return float(0.4 + 0.6 * t * t * (3.0 - 2.0 * t));
}

class GrassSource final : public ItemSource {
public:
    explicit GrassSource(const GrassParams& p)
        : ItemSource("grass", p.placement.count, uint32_t(p.segments)), p_(p),
          flags_(p.alphaMatte ? uint32_t(kTriangleAlphaMatte) : 0u), vertices_(p.segments + 2),
          mask_(p.clump.seed, p.clump.noise), strata_(p.placement) {
        // Vertex j of the strip sits at s_j along the blade: the first two form the root edge,
        // the others climb in equal steps, alternating sides, up to the tip (j = V - 1) where the
        // width has tapered to zero. Every triangle thus spans both sides at distinct heights and
        // cannot be degenerate while height and width are positive.
        for (int j = 0; j < vertices_; ++j) {
            float s = float(std::max(0, j - 1)) / float(vertices_ - 2);
            along_[j] = s;
            alongSq_[j] = s * s;
            halfWidth_[j] = (j % 2 ? 0.5f : -0.5f) * (1.0f - s);
        }
        h0_ = float(p.height.x), hSpan_ = float(p.height.y - p.height.x);
        w0_ = float(p.width.x), wSpan_ = float(p.width.y - p.width.x);
        b0_ = float(p.bend.x), bSpan_ = float(p.bend.y - p.bend.x);
        yaw0_ = float(p.orientationDeg.x * kDegree);
        yawSpan_ = float((p.orientationDeg.y - p.orientationDeg.x) * kDegree);
    }

    uint64_t residentBytes() const override { return p_.placement.residentBytes(); }
    size_t read(std::span<Triangle> out) override {
        p_.placement.prepare();
        return ItemSource::read(out);
    }

protected:
    void item(uint64_t blade, Triangle* out) const override {
        Rng rng(hashIndex(p_.seed, blade));
        double x, z;
        const float vigor = drawRoot(p_, strata_, p_.clump.enabled ? &mask_ : nullptr, blade, rng, x, z);
        const glm::vec3 root(float(x), float(p_.placement.groundHeight(x, z)), float(z));
        const float height = (h0_ + hSpan_ * rng.uniformFloat()) * vigor;
        const float width = w0_ + wSpan_ * rng.uniformFloat();
        const float reach = (b0_ + bSpan_ * rng.uniformFloat()) * height;
        const float yaw = yaw0_ + yawSpan_ * rng.uniformFloat();
        const float c = std::cos(yaw), s = std::sin(yaw);

        // The centre line is the parabola (forward, up) = (reach s^2, height s): the tip is
        // exactly `height` above the root and `reach` ahead of it.
        glm::vec3 v[kMaxSegments + 2];
        for (int j = 0; j < vertices_; ++j) {
            const float side = width * halfWidth_[j], forward = reach * alongSq_[j];
            v[j] = glm::vec3(root.x + c * forward - s * side, root.y + height * along_[j], root.z + s * forward + c * side);
        }
        // A strip: flip every other triangle so that all of them wind the same way.
        for (int j = 0; j + 2 < vertices_; ++j) {
            Triangle& t = out[j];
            t.v[0] = v[j + (j & 1)];
            t.v[1] = v[j + 1 - (j & 1)];
            t.v[2] = v[j + 2];
            t.flags = flags_;
        }
    }

private:
    GrassParams p_;
    uint32_t flags_;
    int vertices_;
    Fbm mask_;
    Strata strata_;
    float along_[kMaxSegments + 2], alongSq_[kMaxSegments + 2], halfWidth_[kMaxSegments + 2];
    float h0_, hSpan_, w0_, wSpan_, b0_, bSpan_, yaw0_, yawSpan_;
};

void requirePositive(const JsonParams& j, const char* key, const glm::dvec2& r, double hi) {
    if (!(r.x > 0 && r.y <= hi)) fail(j.where(key), "must lie in (0, {}], got [{}, {}]", hi, r.x, r.y);
}

}  // namespace

GrassParams parseGrassParams(const SourceRequest& request) {
    JsonParams j(request.params, request.file, request.path);
    GrassParams p;
    p.segments = int(j.integer("segments", p.segments, 3, kMaxSegments));
    p.placement = parsePlacement(j, 10000, kMaxSceneTriangles / uint64_t(p.segments));
    p.height = j.range("height", p.height);
    p.width = j.range("width", p.width);
    p.bend = j.range("bend", p.bend);
    p.orientationDeg = j.range("orientation_deg", p.orientationDeg);
    p.alphaMatte = j.boolean("alpha_matte", p.alphaMatte);
    p.seed = j.seed("seed", p.seed);
    p.clump.seed = hashIndex(p.seed, kClumpStream) >> 1;  // >> 1: expressible as a JSON seed
    if (const nlohmann::json* c = j.raw("clump")) {
        JsonParams cj(*c, j.file(), j.path("clump"));
        ClumpParams& m = p.clump;
        m.enabled = cj.boolean("enabled", true);
        m.noise.frequency = cj.number("frequency", m.noise.frequency);
        m.noise.octaves = int(cj.integer("octaves", m.noise.octaves, 1, 8));
        m.threshold = cj.number("threshold", m.threshold);
        m.edge = cj.number("edge", m.edge);
        m.tries = int(cj.integer("tries", m.tries, 1, 64));
        m.seed = cj.seed("seed", m.seed);
        cj.finish();
        if (!(m.noise.frequency > 0 && m.noise.frequency <= 1e6))
            fail(cj.where("frequency"), "must be in (0, 1e6], got {}", m.noise.frequency);
        if (!(m.threshold >= -1 && m.threshold <= 1)) fail(cj.where("threshold"), "must be in [-1, 1], got {}", m.threshold);
        if (!(m.edge > 0)) fail(cj.where("edge"), "must be positive, got {}", m.edge);
    }
    j.finish();
    requirePositive(j, "height", p.height, 1e6);
    requirePositive(j, "width", p.width, 1e6);
    if (!(p.bend.x >= -4 && p.bend.y <= 4)) fail(j.where("bend"), "must lie in [-4, 4], got [{}, {}]", p.bend.x, p.bend.y);
    if (!(p.orientationDeg.x >= -3600 && p.orientationDeg.y <= 3600))
        fail(j.where("orientation_deg"), "must lie in [-3600, 3600], got [{}, {}]", p.orientationDeg.x, p.orientationDeg.y);
    return p;
}

TriangleSourcePtr makeGrassSource(const GrassParams& params) { return std::make_unique<GrassSource>(params); }

glm::dvec3 grassBladeRoot(const GrassParams& params, uint64_t blade) {
    Rng rng(hashIndex(params.seed, blade));
    const Fbm mask(params.clump.seed, params.clump.noise);
    double x, z;
    drawRoot(params, Strata(params.placement), params.clump.enabled ? &mask : nullptr, blade, rng, x, z);
    return {x, params.placement.groundHeight(x, z), z};
}

}  // namespace penumbra
