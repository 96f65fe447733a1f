#pragma once
/// @file TexelIndex.h
/// @brief Texel indices from the doubles a rasterizer computes. Spans and bounds may be infinite
/// (an edge parallel to the rows, a vertex on the light's plane) or NaN, and converting those to
/// int is undefined behaviour, so every conversion clamps in double first.

namespace penumbra {

/// @brief @p value clamped to [@p lo, @p hi] and converted; NaN gives @p lo.
inline int clampedTexel(double value, int lo, int hi) {
    if (!(value >= lo)) return lo;
    if (!(value <= hi)) return hi;
    return int(value);
}

}  // namespace penumbra
