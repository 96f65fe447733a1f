#pragma once
/// @file GltfElements.h
/// @brief Element reads of one glTF accessor, sparse substitutions included: the one place that
/// turns "element i of accessor a" into bytes.
///
/// Memory contract: a dense accessor holds nothing; a sparse one holds its substituted indices
/// (4 bytes each, gltfSparseBytes()), read and checked once when the reader is made. Values are
/// read window by window through GltfBytes, as dense elements are.

#include "stream/GltfBytes.h"
#include "stream/GltfDocument.h"

#include <cstdint>
#include <vector>

namespace penumbra {

/// @brief Bytes a reader of accessor @p accessor holds resident: its sparse indices, or 0.
uint64_t gltfSparseBytes(const GltfDocument& doc, int accessor);

class GltfElements {
public:
    /// @param where the prefix of every message ("FILE: mesh M primitive P").
    /// @throw InputError naming the accessor when its sparse indices are not strictly increasing
    ///        or reach past its count.
    GltfElements(const GltfDocument& doc, GltfBytes& bytes, int accessor, const std::string& where);

    const GltfAccessor& accessor() const { return *a_; }

    /// @brief The @ref GltfAccessor::elementBytes bytes of element @p i (< count): a sparse
    /// substitution, else the bufferView's element; nullptr when the element is zero (no
    /// bufferView and no substitution). Valid until the next read of @p bytes.
    const uint8_t* at(uint64_t i);

private:
    const GltfAccessor* a_;
    GltfBytes* bytes_;
    std::vector<uint32_t> substituted_;  ///< sparse indices, strictly increasing
    size_t cursor_ = 0;                  ///< where the last look-up ended (reads run mostly in order)
};

}  // namespace penumbra
