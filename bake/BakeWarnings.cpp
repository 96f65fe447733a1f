#include "bake/BakeWarnings.h"

#include "bake/Scene.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <glm/geometric.hpp>

namespace penumbra {
namespace {

/// True when some receiver lies strictly on the emitting side of the planar light @p light.
bool anyReceiverInFront(const LightDesc& light, const ReceiverSet& set) {
    const glm::dvec3 n = light.emitterNormal();
    // Every point of a planar light lies in its plane, so the plane through one of its points
    // decides exactly which receivers it can reach. A polygon has no centre (it was taken as the
    // origin, and a polygon lighting the floor was said to light nothing): its first vertex.
    const glm::dvec3 onPlane = light.type == LightType::Polygon && !light.polygon.empty() ? light.polygon[0] : light.center;
    for (const glm::vec3& r : set.position)
        if (glm::dot(glm::dvec3(r) - onPlane, n) > 0) return true;
    return false;
}

/// True when some receiver's surface faces some direction of the sun @p light: its normal within
/// 90 degrees plus the disk's radius of the direction towards the sun. A receiver without a
/// normal counts as facing it.
bool anyReceiverFacingSun(const LightDesc& light, const ReceiverSet& set) {
    const glm::dvec3 travel = glm::normalize(light.direction);
    const double sinRadius = std::sin(std::min(light.angularDiameterDeg, 180.0) * M_PI / 360.0);
    for (const glm::vec3& normal : set.normal) {
        const glm::dvec3 n(normal);
        const double length = glm::length(n);
        // A margin of a millionth: only a sun clearly below every receiver's horizon is warned of.
        if (!(length > 0) || glm::dot(n, travel) < (sinRadius + 1e-6) * length) return true;
    }
    return set.normal.empty();
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

/// The light's narrowest width: across a rect's shorter side, a disk's or sphere's diameter, a
/// polygon's area over its longest edge, a sun's disk of directions at unit distance.
double narrowestWidth(const LightDesc& light) {
    switch (light.type) {
        case LightType::Rect: return std::min(glm::length(light.u), glm::length(light.v));
        case LightType::Disk:
        case LightType::Sphere: return 2 * light.radius;
        case LightType::Sun: return 2 * sunDirectionDisk(light).radius;
        case LightType::Polygon: break;
    }
    double longest = 0;
    for (size_t i = 0; i < light.polygon.size(); ++i)
        longest = std::max(longest, glm::length(light.polygon[(i + 1) % light.polygon.size()] - light.polygon[i]));
    return longest > 0 ? light.area() / longest : 0.0;
}

/// A light whose float32 samples cannot stratify it: far from the origin the float grid is
/// coarser than its strata, so the samples collapse onto a few points or a line. The bake is
/// then of a different light, and slow: the sample mask table needs samples that span an area.
std::optional<std::string> sampleSpacingWarning(const LightDesc& light) {
    const bool sun = light.type == LightType::Sun;
    // A sun's samples are directions near unit length; other lights' are points.
    double farthest = sun ? 1.0 : std::max({std::abs(light.center.x), std::abs(light.center.y), std::abs(light.center.z)});
    for (const glm::dvec3& p : light.outline()) farthest = std::max({farthest, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
    const float there = float(farthest);
    const double spacing = std::isfinite(there) ? double(std::nextafter(there, INFINITY)) - double(there) : INFINITY;
    const double width = narrowestWidth(light), stratum = width / std::sqrt(double(std::max(light.samples, 1)));
    if (!(width > 0) || !(spacing > stratum)) return std::nullopt;
    const std::string where = sun ? "as unit directions" : fmt::format("at {:.3g} from the origin", farthest);
    return fmt::format("{}: its {} samples are float32, which {} are {:.3g} apart: coarser than its strata ({:.3g} across a width of "
                       "{:.3g}), so they collapse onto a few points or a line, and it bakes as a different and much slower light; {}",
                       light.where, light.samples, where, spacing, stratum, width,
                       sun ? "widen its angular_diameter_deg" : "move the scene nearer the origin");
}

}  // namespace

std::vector<std::string> bakeWarnings(const nlohmann::json& receivers, const ReceiverSet& set, const std::vector<LightDesc>& lights,
                                      const std::string& sceneFile) {
    std::vector<std::string> warnings;
    if (set.size() == 0) {
        const std::string line = noReceivers(receivers.is_object() ? receivers.value("type", std::string()) : std::string());
        warnings.push_back(sceneFile.empty() ? line : sceneFile + ": " + line);
        return warnings;
    }
    for (const LightDesc& light : lights)
        if (std::optional<std::string> spacing = sampleSpacingWarning(light)) warnings.push_back(std::move(*spacing));
    for (const LightDesc& light : lights) {
        if (light.type == LightType::Sun && !anyReceiverFacingSun(light, set)) {
            const glm::dvec3 d = light.direction;
            warnings.push_back(fmt::format("{}: travels away from every receiver's surface (its direction is ({:.3g}, {:.3g}, {:.3g}), "
                                           "and every receiver's normal points along it), so it lights nothing; negate its "
                                           "\"direction\" to turn it around",
                                           light.where, d.x, d.y, d.z));
            continue;
        }
        const glm::dvec3 n = light.emitterNormal();
        if (n == glm::dvec3(0.0) || anyReceiverInFront(light, set)) continue;
        warnings.push_back(fmt::format("{}: faces away from every receiver (it emits towards ({:.3g}, {:.3g}, {:.3g})), so it "
                                       "lights nothing; {}",
                                       light.where, n.x, n.y, n.z, howToTurn(light.type)));
    }
    return warnings;
}

std::optional<std::string> epsilonWarning(const ReceiverSet& set, double epsilon, double length) {
    if (set.size() == 0 || !(epsilon > 0)) return std::nullopt;
    glm::vec3 lo(INFINITY), hi(-INFINITY);
    for (const glm::vec3& p : set.position) lo = glm::min(lo, p), hi = glm::max(hi, p);
    const glm::vec3 size = hi - lo;
    const double extent = std::max({double(size.x), double(size.y), double(size.z)});
    const double eps = epsilon * length;
    if (!(extent > 0) || !(eps > 0.01 * extent)) return std::nullopt;
    return fmt::format("the rule's receiver epsilon is {:.3g} (bake.epsilon {:g} times the largest receiver coordinate, {:.3g}), "
                       "{:.3g} % of the receivers' extent ({:.3g}): a blocker nearer than that to a receiver casts no shadow on it; "
                       "move the scene nearer the origin or lower bake.epsilon",
                       eps, epsilon, length, 100 * eps / extent, extent);
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
        if (leaky.crossing)
            what.push_back(fmt::format("{} of its solids {} faces that cross one another, or more than two at one edge (a surface pushed through itself)",
                                       leaky.crossing, leaky.crossing == 1 ? "has" : "have"));
        if (leaky.unchecked)
            what.push_back(fmt::format("{} of its solids {} more than {} triangles, too many to check for faces that cross",
                                       leaky.unchecked, leaky.unchecked == 1 ? "has" : "have", kMaxCheckedSolidTriangles));
        warnings.push_back(fmt::format("{} is marked closed, but {} ({} triangles); cast as open surfaces, which keeps every shadow",
                                       entry, fmt::join(what, " and "), leaky.triangles));
    }
    return warnings;
}

}  // namespace penumbra
