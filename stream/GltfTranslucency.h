#pragma once
/// @file GltfTranslucency.h
/// @brief The translucent materials of a glTF document (issue #15): `alphaMode: "BLEND"` and
/// `KHR_materials_transmission`, as the alpha ids of stream/Translucency.h.
///
/// With base colour factor (C, a) and transmission factor tau (KHR_materials_transmission; the
/// textures are not read), the per-channel transmittance is
///  - BLEND: t = (1 - a) + a tau C, tau = 1 without the extension (a stained filter covering a);
///  - OPAQUE with tau > 0: t = tau C (a = 1);
///  - otherwise (OPAQUE without transmission, MASK): opaque, id 0; cut-outs are another reader's.

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace penumbra {

/// @brief One alpha id per material of @p root (0: opaque, else a translucent id).
/// @throw InputError naming @p path and the material for a factor that is not a number in [0, 1]
///        or an unknown alphaMode.
std::vector<uint32_t> gltfMaterialAlphaIds(const std::string& path, const nlohmann::json& root);

}  // namespace penumbra
