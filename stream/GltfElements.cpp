#include "stream/GltfElements.h"

#include "stream/util/Error.h"

#include <algorithm>
#include <cstring>
#include <limits>

namespace penumbra {

uint64_t gltfSparseBytes(const GltfDocument& doc, int accessor) {
    if (accessor < 0) return 0;
    const GltfAccessor& a = doc.accessors[size_t(accessor)];
    return a.sparse ? a.sparse->count * sizeof(uint32_t) : 0;
}

GltfElements::GltfElements(const GltfDocument& doc, GltfBytes& bytes, int accessor, const std::string& where)
    : a_(&doc.accessors[size_t(accessor)]), bytes_(&bytes) {
    if (!a_->sparse) return;
    const GltfSparse& s = *a_->sparse;
    const uint32_t size = uint32_t(gltfComponentBytes(s.indexType));
    substituted_.reserve(size_t(s.count));
    for (uint64_t j = 0; j < s.count; ++j) {
        const uint8_t* p = bytes.at(s.indicesView, s.indicesOffset + j * size, size);
        uint32_t index = 0;
        if (size == 1) index = *p;
        else if (size == 2) {
            uint16_t x;
            std::memcpy(&x, p, 2);
            index = x;
        } else {
            std::memcpy(&index, p, 4);
        }
        // The specification requires strictly increasing indices; a binary search relies on it.
        if (index >= a_->count)
            fail(where, "accessor {} sparse index {} is {}, but the accessor has {} elements", accessor, j, index, a_->count);
        if (j > 0 && index <= substituted_.back())
            fail(where, "accessor {} sparse index {} is {}, not above the one before ({}): sparse indices must increase",
                 accessor, j, index, substituted_.back());
        substituted_.push_back(index);
    }
}

const uint8_t* GltfElements::at(uint64_t i) {
    if (!substituted_.empty() && i <= std::numeric_limits<uint32_t>::max()) {
        const uint32_t key = uint32_t(i);
        // Reads mostly run in order: try where the last one ended before searching.
        size_t j = cursor_;
        if (!(j < substituted_.size() && substituted_[j] >= key && (j == 0 || substituted_[j - 1] < key)))
            j = size_t(std::lower_bound(substituted_.begin(), substituted_.end(), key) - substituted_.begin());
        cursor_ = j;
        if (j < substituted_.size() && substituted_[j] == key) {
            const GltfSparse& s = *a_->sparse;
            return bytes_->at(s.valuesView, s.valuesOffset + j * a_->elementBytes, a_->elementBytes);
        }
    }
    if (a_->bufferView < 0) return nullptr;
    return bytes_->at(a_->bufferView, a_->byteOffset + i * a_->stride, a_->elementBytes);
}

}  // namespace penumbra
