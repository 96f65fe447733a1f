#pragma once
/// @file Noise.h
/// @brief Deterministic 2D gradient noise and its fractal sum (fBm): pure functions of a seed and
/// a point, with no tables and no state, so any thread can evaluate any point and get the same
/// bits. Terrain heights and the grass clump mask are built on these.

#include <cstdint>

namespace penumbra {

/// @brief Perlin-style gradient noise at (x, y), scaled to [-1, 1].
///
/// Lattice gradients are 16 unit directions picked by hashing (seed, cell); the quintic fade
/// makes the field C2-continuous. It is 0 at every lattice point, which is why fbm() shifts
/// each octave by a seed-derived offset.
/// @param seed selects an independent field
double gradientNoise(uint64_t seed, double x, double y);

/// Parameters of a fractal sum of gradient noise octaves.
struct FbmParams {
    int octaves = 5;          ///< number of octaves summed, >= 1
    double frequency = 0.1;   ///< cycles per world unit of the first octave
    double lacunarity = 2.0;  ///< frequency factor between octaves
    double gain = 0.5;        ///< amplitude factor between octaves
};

/// @brief Fractal Brownian motion: the weighted octave sum, normalised so that it stays in [-1, 1].
/// Each octave has its own seed and a seed-derived shift (gradient noise is 0 at lattice points,
/// so unshifted octaves would all vanish together at the origin).
double fbm(uint64_t seed, const FbmParams& params, double x, double y);

/// @brief fbm() with the per-octave seeds, shifts and weights worked out once: the same values,
/// bit for bit, for callers that evaluate one field at many points (terrain, clump masks).
class Fbm {
public:
    static constexpr int kMaxOctaves = 16;
    /// @param params octaves are clamped to 1..kMaxOctaves
    Fbm(uint64_t seed, const FbmParams& params);
    double operator()(double x, double y) const;

private:
    struct Octave {
        uint64_t seed;
        double frequency, weight, offsetX, offsetY;
    };
    Octave octaves_[kMaxOctaves];
    int count_;
};

}  // namespace penumbra
