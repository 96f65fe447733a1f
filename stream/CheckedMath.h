#pragma once
/// @file CheckedMath.h
/// @brief The one helper through which every count or size taken from input is multiplied
/// (pixels = width x height x layers, voxels, triangles = instances x triangles each, samples),
/// so that an overflow, or a product beyond what the code can index, is a clean error naming the
/// key instead of a wrapped number that allocates too little or loops for ever.

#include "stream/Error.h"

#include <fmt/ranges.h>

#include <cstdint>
#include <initializer_list>
#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace penumbra {

/// Most triangles one scene may stream (a bake needs 40 bytes of bucket file per triangle, so
/// this is 44 TB): a generator asked for more is refused at its count or density key.
inline constexpr uint64_t kMaxSceneTriangles = uint64_t(1) << 40;

/// @brief The product of @p factors, or nullopt when it overflows 64 bits (for callers with
/// messages of their own).
inline std::optional<uint64_t> productOf(std::span<const uint64_t> factors) {
    uint64_t product = 1;
    for (uint64_t f : factors)
        if (__builtin_mul_overflow(product, f, &product)) return std::nullopt;
    return product;
}

/// @brief The product of @p factors, refused when it overflows 64 bits or exceeds @p limit.
/// @param where the key, "scene.json: receivers.width"; @param what the unit, "pixels".
/// @throw InputError "WHERE: 65536 x 65536 x 2 = 8589934592 pixels, more than the limit of
///        4294967295" (or "... overflows 64 bits").
inline uint64_t checkedProduct(std::initializer_list<uint64_t> factors, uint64_t limit, const std::string& where,
                               std::string_view what) {
    const std::optional<uint64_t> checked = productOf(std::span<const uint64_t>(factors.begin(), factors.size()));
    if (!checked) fail(where, "{} {} overflows 64 bits", fmt::join(factors, " x "), what);
    const uint64_t product = *checked;
    if (product > limit)
        fail(where, "{} = {} {}, more than the limit of {}", fmt::join(factors, " x "), product, what, limit);
    return product;
}

/// @brief @p a + @p b, refused like checkedProduct() when it overflows or exceeds @p limit.
inline uint64_t checkedSum(uint64_t a, uint64_t b, uint64_t limit, const std::string& where, std::string_view what) {
    uint64_t sum = 0;
    if (__builtin_add_overflow(a, b, &sum)) fail(where, "{} + {} {} overflows 64 bits", a, b, what);
    if (sum > limit) fail(where, "{} + {} = {} {}, more than the limit of {}", a, b, sum, what, limit);
    return sum;
}

}  // namespace penumbra
