#include "procedural/Noise.h"

#include "stream/util/Random.h"

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

// 16 unit vectors at multiples of 22.5 degrees; more directions than Perlin's 4 diagonals give
// fewer axis-aligned artefacts in a heightfield seen from above.
constexpr double kGradients[16][2] = {
    {1.0, 0.0},         {0.9238795325112867, 0.3826834323650898},   {0.7071067811865476, 0.7071067811865476},
    {0.3826834323650898, 0.9238795325112867},                       {0.0, 1.0},
    {-0.3826834323650898, 0.9238795325112867},                      {-0.7071067811865476, 0.7071067811865476},
    {-0.9238795325112867, 0.3826834323650898},                      {-1.0, 0.0},
    {-0.9238795325112867, -0.3826834323650898},                     {-0.7071067811865476, -0.7071067811865476},
    {-0.3826834323650898, -0.9238795325112867},                     {0.0, -1.0},
    {0.3826834323650898, -0.9238795325112867},                      {0.7071067811865476, -0.7071067811865476},
    {0.9238795325112867, -0.3826834323650898}};

/// Lattice coordinate of a floored value. Beyond +-2^62 the fraction is meaningless anyway; the
/// clamp only keeps the conversion defined.
int64_t lattice(double floored) {
    constexpr double kLimit = 4.6e18;
    return floored > kLimit ? int64_t(kLimit) : (floored < -kLimit ? -int64_t(kLimit) : int64_t(floored));
}

/// Hash of one lattice row; the four corners of a cell share two of these, so a noise value
/// costs two full mixes plus one multiply per corner.
uint64_t rowHash(uint64_t seed, int64_t iy) { return mix64(seed ^ (uint64_t(iy) * 0xC2B2AE3D27D4EB4Full)); }

/// Gradient of column @p ix in a hashed row, dotted with the offset (dx, dy). The multiply
/// carries every input bit into the top four, which pick one of 16 directions.
double corner(uint64_t row, int64_t ix, double dx, double dy) {
    const uint64_t h = (row ^ (uint64_t(ix) * 0x9E3779B97F4A7C15ull)) * 0xD6E8FEB86659FD93ull;
    const double* g = kGradients[h >> 60];
    return g[0] * dx + g[1] * dy;
}

double fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

}  // namespace

double gradientNoise(uint64_t seed, double x, double y) {
    const double fx = std::floor(x), fy = std::floor(y);
    const int64_t ix = lattice(fx), iy = lattice(fy);
    const double tx = x - fx, ty = y - fy;
    const uint64_t r0 = rowHash(seed, iy), r1 = rowHash(seed, iy + 1);
    const double n00 = corner(r0, ix, tx, ty), n10 = corner(r0, ix + 1, tx - 1.0, ty);
    const double n01 = corner(r1, ix, tx, ty - 1.0), n11 = corner(r1, ix + 1, tx - 1.0, ty - 1.0);
    const double u = fade(tx), v = fade(ty);
    const double a = n00 + u * (n10 - n00), b = n01 + u * (n11 - n01);
    // With unit gradients 2D gradient noise stays within +-sqrt(1/2); scale that to +-1. The clamp
    // only guards against rounding at the extremes.
    return std::clamp((a + v * (b - a)) * 1.4142135623730951, -1.0, 1.0);
}

Fbm::Fbm(uint64_t seed, const FbmParams& p) : count_(std::clamp(p.octaves, 1, kMaxOctaves)) {
    double amplitude = 1, frequency = p.frequency, norm = 0;
    for (int k = 0; k < count_; ++k) {
        const uint64_t octaveSeed = hashIndex(seed, uint64_t(k));
        // A per-octave shift of up to 256 cells, so that octaves do not all vanish at the origin.
        octaves_[k] = {octaveSeed, frequency, amplitude, double(octaveSeed & 0xFFFF) * (1.0 / 256.0),
                       double((octaveSeed >> 16) & 0xFFFF) * (1.0 / 256.0)};
        norm += amplitude;
        amplitude *= p.gain;
        frequency *= p.lacunarity;
    }
    for (int k = 0; k < count_; ++k) octaves_[k].weight /= norm;
}

double Fbm::operator()(double x, double y) const {
    double sum = 0;
    for (int k = 0; k < count_; ++k) {
        const Octave& o = octaves_[k];
        sum += o.weight * gradientNoise(o.seed, x * o.frequency + o.offsetX, y * o.frequency + o.offsetY);
    }
    return std::clamp(sum, -1.0, 1.0);
}

double fbm(uint64_t seed, const FbmParams& p, double x, double y) { return Fbm(seed, p)(x, y); }

}  // namespace penumbra
