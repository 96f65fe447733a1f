#pragma once
/// @file Random.h
/// @brief Counter-based hashing and a tiny RNG. Everything random in penumbra (jitter, sample-set
/// assignment, procedural placement) is a pure function of a seed and an index, so results do
/// not depend on thread count or on the order work is scheduled in.

#include <cstdint>

namespace penumbra {

/// SplitMix64 finaliser: a strong 64-bit mix, cheap enough for per-receiver use.
constexpr uint64_t mix64(uint64_t x) {
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

/// Hash of a seed and up to three indices.
constexpr uint64_t hashIndex(uint64_t seed, uint64_t a, uint64_t b = 0, uint64_t c = 0) {
    return mix64(mix64(mix64(seed ^ mix64(a)) ^ b) ^ c);
}

/// @brief Sequential generator over a hashed stream; copyable value type.
class Rng {
public:
    explicit constexpr Rng(uint64_t seed) : state_(mix64(seed)) {}
    constexpr uint64_t next() { return mix64(state_ += 0x9E3779B97F4A7C15ull); }
    /// Uniform in [0, 1) with 24 random bits, so the value converts to float exactly.
    constexpr float uniformFloat() { return float(next() >> 40) * (1.0f / 16777216.0f); }
    /// Uniform in [0, 1) with 53 random bits.
    constexpr double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }
    constexpr double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }

private:
    uint64_t state_;
};

}  // namespace penumbra
