#pragma once
/// @file SimdLevel.h
/// @brief The instruction sets of the cast's kernels (hard-shadow blocks, the sample mask table's
/// lines, the leaf prefilter, penumbra volumes) and the attribute their AVX2 forms compile with.
///
/// Every kernel gives the scalar code's bits at every level: lanes run the scalar operations in
/// the scalar order, without fused multiply-add, so `--simd` changes the speed and nothing else.

#include <cstdint>
#include <string_view>

namespace penumbra {

/// The attribute of every AVX2 kernel of the cast: "avx2" deliberately without "fma", because a
/// fused multiply-add would round differently from the scalar rule, and each kernel must give the
/// scalar code's bits.
#define PENUMBRA_AVX2 __attribute__((target("avx2")))

/// Which instruction set evaluates the kernels. Auto picks the best the CPU supports.
enum class SimdLevel : uint8_t { Scalar, Sse2, Avx2, Auto };

/// @brief Whether this CPU can run @p level.
bool simdSupported(SimdLevel level);

/// @brief "scalar", "sse2", "avx2" or "auto".
const char* simdName(SimdLevel level);

/// @brief Parses a name of simdName(); @throw InputError naming @p where and the value.
SimdLevel parseSimdLevel(std::string_view name, std::string_view where);

}  // namespace penumbra
