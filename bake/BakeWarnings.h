#pragma once
/// @file BakeWarnings.h
/// @brief Warnings that save a bake: inputs that bake without an error but almost certainly not
/// as meant, found once the scan has made the receivers, before hours of casting.

#include "bake/cast/ClosedSolids.h"
#include "bake/light/Light.h"
#include "receivers/ReceiverSet.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace penumbra {

/// @brief The warnings for a bake's receivers and lights, one line each:
/// - a planar light (rect, disk, polygon) that faces away from every receiver: it emits on one
///   side only, so every receiver's irradiance from it is 0 (a swapped `u`/`v`);
/// - no receivers at all: a camera that sees no geometry, receiver meshes that are empty.
/// @param receivers the "receivers" object (its type names the kind in messages).
/// @param sceneFile names the scene in the no-receivers line, as the lights' own `where` does
std::vector<std::string> bakeWarnings(const nlohmann::json& receivers, const ReceiverSet& set, const std::vector<LightDesc>& lights,
                                      const std::string& sceneFile = "");

/// @brief A warning when the rule's receiver epsilon at the largest receiver coordinate,
/// @p epsilon x @p length (BlockingRule.h), is more than 1 % of the receivers' extent: blockers
/// nearer than that to a receiver cast nothing on it, so a scene far from the origin loses its
/// contact shadows (a mesh at 1e6 with the default 1e-5 lost every shadow, silently).
std::optional<std::string> epsilonWarning(const ReceiverSet& set, double epsilon, double length);

struct SceneDesc;

/// @brief One warning per geometry entry marked closed whose solids are not all watertight or
/// are wound inward: such solids are cast as open surfaces, since a wrong mark would lose
/// shadows (bake/cast/EdgeBalance.h). Each names the entry and its file.
std::vector<std::string> leakySolidWarnings(const OpenedSolids& opened, const SceneDesc& scene);

}  // namespace penumbra
