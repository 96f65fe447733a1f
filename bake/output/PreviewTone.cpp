#include "bake/output/PreviewTone.h"

#include <algorithm>

namespace penumbra {

PreviewTone previewTone(std::vector<float>& luminance) {
    float white = 1.f;
    if (!luminance.empty()) {
        const size_t q = std::min(luminance.size() - 1, size_t(0.99 * double(luminance.size())));
        std::nth_element(luminance.begin(), luminance.begin() + long(q), luminance.end());
        white = luminance[q] > 0 ? luminance[q] : 1.f;
    }
    return PreviewTone{0.92f / white};
}

}  // namespace penumbra
