#pragma once
/// @file ReferenceCaster.h
/// @brief `--method reference`: plain ray casting of every receiver-to-sample segment against
/// every triangle, deciding each relation with the shared blocking rule (BlockingRule.h).
/// O(receivers x samples x triangles): a correctness oracle for small scenes, not a renderer.

#include "bake/rule/BlockingRule.h"
#include "bake/light/Light.h"
#include "bake/cast/VisibilityMasks.h"
#include "receivers/ReceiverSet.h"
#include "stream/Triangle.h"

#include <functional>
#include <span>

namespace penumbra {

/// @brief Fills masks for all receivers. @p progress (optional) is called with receivers done.
VisibilityMasks castReference(const LightSamples& samples, const ReceiverSet& receivers,
                              std::span<const uint32_t> sampleSetOf, std::span<const Triangle> triangles,
                              const ReceiverEpsilon& epsilon, const std::function<void(uint64_t)>& progress = {});

}  // namespace penumbra
