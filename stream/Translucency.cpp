#include "stream/Translucency.h"

#include "stream/util/Error.h"

#include <map>
#include <memory>
#include <mutex>

namespace penumbra {
namespace {

constexpr uint32_t kTranslucentCapacity = 1u << 16;

/// Append-only and process-wide, so that any reader (a glTF material, a scene entry) can name a
/// translucency without a table handed down to it; an id, once given, never changes meaning.
struct TranslucencyTable {
    std::mutex mutex;
    std::map<OpticalDepth, uint32_t> ids;
    std::unique_ptr<OpticalDepth[]> depths{new OpticalDepth[kTranslucentCapacity]{}};
};

TranslucencyTable& table() {
    static TranslucencyTable t;
    return t;
}

}  // namespace

uint32_t translucentId(const glm::dvec3& t, const std::string& where) {
    const OpticalDepth depth{quantizeDepth(t.r), quantizeDepth(t.g), quantizeDepth(t.b)};
    TranslucencyTable& tt = table();
    std::lock_guard lock(tt.mutex);
    if (auto it = tt.ids.find(depth); it != tt.ids.end()) return kTranslucentIdBase + it->second;
    if (tt.ids.size() >= kTranslucentCapacity)
        fail(where, "more than {} different translucent colours in one process", kTranslucentCapacity);
    const uint32_t index = uint32_t(tt.ids.size());
    tt.depths[index] = depth;
    tt.ids.emplace(depth, index);
    return kTranslucentIdBase + index;
}

const OpticalDepth& opticalDepthOf(uint32_t id) {
    static const OpticalDepth none{};
    const uint32_t index = id - kTranslucentIdBase;
    return index < kTranslucentCapacity ? table().depths[index] : none;
}

void checkUnitInterval(double value, const std::string& where) {
    if (!(value >= 0.0 && value <= 1.0)) fail(where, "must be a number in [0, 1], got {}", value);
}

}  // namespace penumbra
