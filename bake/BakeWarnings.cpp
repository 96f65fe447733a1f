#include "bake/BakeWarnings.h"

#include "bake/Scene.h"

#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <glm/geometric.hpp>

namespace penumbra {
namespace {

/// True when some receiver lies strictly on the emitting side of the planar light @p light.
bool anyReceiverInFront(const LightDesc& light, const ReceiverSet& set) {
    const glm::dvec3 n = light.emitterNormal();
    // Every point of a planar light lies in its plane, so the plane through its centre decides
    // exactly which receivers it can reach.
    for (const glm::vec3& r : set.position)
        if (glm::dot(glm::dvec3(r) - light.center, n) > 0) return true;
    return false;
}

/// How to turn the light around, by its type.
const char* howToTurn(LightType type) {
    switch (type) {
        case LightType::Rect: return "swap \"u\" and \"v\" to turn it around";
        case LightType::Disk: return "negate its \"normal\" to turn it around";
        default: return "list its \"vertices\" in the other order to turn it around";
    }
}

std::string noReceivers(const std::string& type) {
    if (type == "camera") return "receivers: the camera sees no geometry (check eye, target, up and fov_deg); the image is empty";
    if (type == "lightmap") return "receivers: the receiver meshes cover no texel; the lightmaps are empty";
    if (type == "vertices") return "receivers: the receiver meshes have no vertices; nothing is baked";
    if (type == "volume") return "receivers: the volume holds no voxel; nothing is baked";
    return "receivers: there are none; nothing is baked";
}

}  // namespace

std::vector<std::string> bakeWarnings(const nlohmann::json& receivers, const ReceiverSet& set, const std::vector<LightDesc>& lights) {
    std::vector<std::string> warnings;
    if (set.size() == 0) {
        warnings.push_back(noReceivers(receivers.is_object() ? receivers.value("type", std::string()) : std::string()));
        return warnings;
    }
    for (const LightDesc& light : lights) {
        const glm::dvec3 n = light.emitterNormal();
        if (n == glm::dvec3(0.0) || anyReceiverInFront(light, set)) continue;
        warnings.push_back(fmt::format("{}: faces away from every receiver (it emits towards ({:.3g}, {:.3g}, {:.3g})), so it "
                                       "lights nothing; {}",
                                       light.where, n.x, n.y, n.z, howToTurn(light.type)));
    }
    return warnings;
}

std::vector<std::string> leakySolidWarnings(const OpenedSolids& opened, const SceneDesc& scene) {
    std::vector<std::string> warnings;
    for (const OpenedSolids::Leaky& leaky : opened.leaky) {
        std::string entry = "the geometry";
        if (leaky.part < scene.geometry.size()) {
            const GeometryDesc& g = scene.geometry[leaky.part];
            entry = g.path;
            if (const auto it = g.params.find("path"); it != g.params.end() && it->is_string())
                entry += fmt::format(" ({})", std::filesystem::path(it->get<std::string>()).filename().string());
        }
        std::vector<std::string> what;
        if (leaky.solids)
            what.push_back(fmt::format("{} of its solids {} not watertight (an edge without its reverse: a hole, a crack or a "
                                       "flipped face)", leaky.solids, leaky.solids == 1 ? "is" : "are"));
        if (leaky.inward)
            what.push_back(fmt::format("{} of its solids {} wound inward (or flat)", leaky.inward, leaky.inward == 1 ? "is" : "are"));
        warnings.push_back(fmt::format("{} is marked closed, but {} ({} triangles); cast as open surfaces, which keeps every shadow",
                                       entry, fmt::join(what, " and "), leaky.triangles));
    }
    return warnings;
}

}  // namespace penumbra
