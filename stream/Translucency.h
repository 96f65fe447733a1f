#pragma once
/// @file Translucency.h
/// @brief Coloured translucent blockers (issue #15): what a translucent triangle lets through,
/// as an exact, order-independent integer optical depth per RGB channel.
///
/// A translucent triangle carries an alpha id >= kTranslucentIdBase in Triangle::flags (so the
/// record stays 40 bytes and is bucketed after every opaque blocker, kTriangleAlphaMatte). The id
/// names an entry of the process-wide translucency table below: the surface's per-channel
/// transmittance t in [0, 1], quantized once to a fixed-point optical depth
///     d = round(-log2(t) * 2^kDepthFractionBits), saturated at kMaxOpticalDepth.
/// A relation's depth is the saturating integer sum over the translucent surfaces its segment
/// crosses (the blocking rule decides "crosses", ties included), which is associative and
/// commutative: the result does not depend on blocker order, tiles, threads or the method. It is
/// turned into a transmittance once, T = 2^(-D / 2^kDepthFractionBits).
/// Error: each surface's log2 t is off by at most 2^-17, so T is within a factor
/// 2^(n 2^-17) (about 5.3e-6 relative per surface) of the float product of n factors. Saturation:
/// t below 2^-64 counts as 2^-64 (still translucent: never opaque, never umbra).

#include "stream/Triangle.h"

#include <glm/vec3.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <string>

namespace penumbra {

/// Alpha ids from here up name translucency table entries (Triangle.h has 24 bits of id).
constexpr uint32_t kTranslucentIdBase = 1u << 23;
/// Fraction bits of an optical depth.
constexpr int kDepthFractionBits = 16;
/// Depth of the darkest transmittance kept, 2^-64 (a sum saturates here too).
constexpr uint32_t kMaxOpticalDepth = 64u << kDepthFractionBits;

/// @brief Per-channel optical depth of one surface or one relation (R, G, B).
using OpticalDepth = std::array<uint32_t, 3>;

/// True when alpha id @p id names a translucent surface.
constexpr bool isTranslucentId(uint32_t id) { return id >= kTranslucentIdBase; }

/// True when a triangle with @p flags can block a relation: it casts shadows and is not
/// translucent (a translucent triangle only attenuates, bake/cast/TranslucentBlockers.h).
constexpr bool blocksAsOpaque(uint32_t flags) { return !(flags & kTriangleNoCast) && !isTranslucentId(alphaIdOf(flags)); }
/// Casts and blocks every segment through it: opaque and without a cut-out (alpha id 0). Only
/// such faces make a closed solid whose faces closed casters may skip.
constexpr bool blocksWhole(uint32_t flags) { return blocksAsOpaque(flags) && alphaIdOf(flags) == 0; }

/// @brief The fixed-point optical depth of transmittance @p t in [0, 1].
inline uint32_t quantizeDepth(double t) {
    if (!(t > 0x1p-64)) return kMaxOpticalDepth;
    const double d = std::nearbyint(-std::log2(t) * double(1u << kDepthFractionBits));
    return d <= 0 ? 0u : d >= double(kMaxOpticalDepth) ? kMaxOpticalDepth : uint32_t(d);
}
/// @brief a + b, saturated at kMaxOpticalDepth (associative and commutative for depths <= max).
constexpr uint32_t addDepth(uint32_t a, uint32_t b) {
    return a + b >= kMaxOpticalDepth ? kMaxOpticalDepth : a + b;
}
/// @brief The transmittance of optical depth @p d: 2^(-d / 2^kDepthFractionBits).
inline double transmittanceOf(uint32_t d) { return d ? std::exp2(-double(d) * 0x1p-16) : 1.0; }

/// @brief The transmittance of a surface of colour @p color (each in [0, 1]) covering the
/// fraction @p opacity and transmitting @p transmission of what it covers:
/// t = (1 - opacity) + opacity * transmission * color. A glTF BLEND material and a scene
/// entry's "translucent" take transmission 1 (a stained filter); KHR_materials_transmission
/// takes its factor (OPAQUE and MASK materials: opacity 1).
inline glm::dvec3 surfaceTransmittance(const glm::dvec3& color, double opacity, double transmission) {
    return glm::dvec3(1.0 - opacity) + opacity * transmission * color;
}

/// @brief The alpha id of a surface with transmittance @p t (each channel in [0, 1]); equal
/// quantized depths share one id. Thread-safe.
/// @throw InputError naming @p where when more than 65,536 distinct transmittances were asked for.
uint32_t translucentId(const glm::dvec3& t, const std::string& where);

/// @brief The optical depth of translucent id @p id (isTranslucentId(id) must hold).
const OpticalDepth& opticalDepthOf(uint32_t id);

/// @brief Checks a declared colour and opacity: finite and in [0, 1].
/// @throw InputError "<where>.<key>: must be in [0, 1], got ..." otherwise.
void checkUnitInterval(double value, const std::string& where);

}  // namespace penumbra
