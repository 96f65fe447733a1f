#pragma once
/// @file BakeCapture.h
/// @brief A bake's results handed back to a library caller (the Python module) instead of, or as
/// well as, being written: the receivers, their shading, the masks and the receiver kind that can
/// still write the CLI's outputs from them later (writeCapturedOutputs, Pipeline.h).

#include "bake/cast/VisibilityMasks.h"
#include "bake/kinds/ReceiverKind.h"
#include "bake/light/Light.h"
#include "bake/shading/ReceiverShading.h"
#include "receivers/ReceiverSet.h"

#include <cstdint>
#include <memory>
#include <vector>

namespace penumbra {

/// @brief Set BakeSettings::capture to one of these; runBake fills it in.
struct BakeCapture {
    /// Asked by the caller: keep every receiver's masks (as --dump does). Costs N x groups words.
    bool wantMasks = false;
    /// Asked by the caller: write the scene's outputs during the bake, as the CLI does.
    bool writeOutputs = false;

    // Filled by runBake.
    ReceiverSet receivers;
    LightSamples samples;
    std::vector<uint32_t> sampleSets;
    ReceiverResults results;
    VisibilityMasks masks;  ///< empty unless wantMasks
    size_t firstPass = 0;   ///< receivers [0, firstPass) are the first pass's
    std::unique_ptr<ReceiverKind> kind;  ///< writes the outputs from the fields above
};

}  // namespace penumbra
