#pragma once
/// @file SceneCaster.h
/// @brief The part every method that holds the whole scene shares (reference, Embree, soft
/// shadow volumes): read the blockers once, show them to the receiver kind, cast the receivers
/// asked for, report their masks. Holding the scene is their nature, not ours: they are peers
/// and alternatives for scenes that fit, not out-of-core methods.

#include "bake/cast/Caster.h"
#include "bake/cast/VisibilityMasks.h"

#include <functional>
#include <memory>
#include <vector>

namespace penumbra {

/// @brief Receivers [@p first, end) of @p set as a set of their own (positions and normals).
ReceiverSet receiversFrom(const ReceiverSet& set, size_t first);

class SceneCaster : public Caster {
public:
    /// Casts every relation of @p targets (sample sets @p sets) against @p all.
    using CastAll = std::function<VisibilityMasks(const ReceiverSet& targets, std::span<const uint32_t> sets,
                                                  std::span<const Triangle> all, const std::function<void(uint64_t)>& progress)>;

    SceneCaster(const CastContext& context, std::string phase, CastAll castAll)
        : c_(context), phase_(std::move(phase)), castAll_(std::move(castAll)) {}

    void cast(TriangleSource& blockers, uint32_t first, const CastSink& sink) override;
    CastStats stats() const override { return stats_; }

protected:
    const CastContext c_;
    /// A method that weighs translucent blockers (CasterTraits::translucency) leaves here, per
    /// target receiver, its per-sample depths or null; they go to CastSink::masksWithDepth.
    std::vector<std::unique_ptr<uint32_t[]>> depths_;

private:
    std::string phase_;
    CastAll castAll_;
    std::vector<Triangle> all_;
    bool read_ = false;
    CastStats stats_;
};

}  // namespace penumbra
