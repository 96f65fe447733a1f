#include "stream/GltfTranslucency.h"

#include "stream/Translucency.h"
#include "stream/util/Error.h"

#include <nlohmann/json.hpp>

namespace penumbra {
namespace {

using Json = nlohmann::json;

/// A factor of material @p what: a number in [0, 1].
double unitFactor(const std::string& path, const std::string& what, const Json& v) {
    if (!v.is_number() || !(v.get<double>() >= 0.0 && v.get<double>() <= 1.0))
        fail(path, "{} must be a number in [0, 1], got {}", what, v.dump());
    return v.get<double>();
}

/// Base colour factor (C, a) of material @p m: read only for a translucent material, since the
/// MASK reader (GltfMaterials.h) and opaque materials use their own part of it, or none.
void baseColor(const std::string& path, const std::string& what, const Json& m, glm::dvec3& color, double& alpha) {
    color = glm::dvec3(1.0), alpha = 1.0;
    if (auto pbr = m.find("pbrMetallicRoughness"); pbr != m.end() && pbr->is_object())
        if (auto f = pbr->find("baseColorFactor"); f != pbr->end()) {
            if (!f->is_array() || f->size() != 4) fail(path, "{} baseColorFactor must hold 4 numbers in [0, 1]", what);
            for (int c = 0; c < 3; ++c) color[c] = unitFactor(path, what + " baseColorFactor", (*f)[size_t(c)]);
            alpha = unitFactor(path, what + " baseColorFactor", (*f)[3]);
        }
}

uint32_t materialAlphaId(const std::string& path, const Json& m, size_t i) {
    const std::string what = fmt::format("material {}", i);
    if (!m.is_object()) fail(path, "{} must be an object", what);
    std::string mode = "OPAQUE";
    if (auto a = m.find("alphaMode"); a != m.end()) {
        if (!a->is_string()) fail(path, "{} alphaMode must be a string", what);
        mode = a->get<std::string>();
        if (mode != "OPAQUE" && mode != "MASK" && mode != "BLEND") fail(path, "{} has an unknown alphaMode \"{}\"", what, mode);
    }
    double transmission = 0.0;
    bool transmits = false;
    if (auto e = m.find("extensions"); e != m.end() && e->is_object())
        if (auto t = e->find("KHR_materials_transmission"); t != e->end()) {
            if (!t->is_object()) fail(path, "{} KHR_materials_transmission must be an object", what);
            transmits = true;
            if (auto f = t->find("transmissionFactor"); f != t->end())
                transmission = unitFactor(path, what + " KHR_materials_transmission transmissionFactor", *f);
        }
    const bool blend = mode == "BLEND", transmissive = mode == "OPAQUE" && transmission > 0.0;
    if (!blend && !transmissive) return 0;
    glm::dvec3 color;
    double alpha;
    baseColor(path, what, m, color, alpha);
    const std::string where = path + ": " + what;
    if (blend) return translucentId(surfaceTransmittance(color, alpha, transmits ? transmission : 1.0), where);
    return translucentId(surfaceTransmittance(color, 1.0, transmission), where);
}

}  // namespace

std::vector<uint32_t> gltfMaterialAlphaIds(const std::string& path, const nlohmann::json& root) {
    std::vector<uint32_t> ids;
    auto materials = root.find("materials");
    if (materials == root.end()) return ids;
    if (!materials->is_array()) fail(path, "materials must be an array");
    for (size_t i = 0; i < materials->size(); ++i) ids.push_back(materialAlphaId(path, (*materials)[i], i));
    return ids;
}

}  // namespace penumbra
