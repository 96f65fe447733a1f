#pragma once
/// @file SourceRegistry.h
/// @brief Geometry types by name: the scene's "geometry" entries are opened through here, so that
/// later stages (procedural generators) add types without the scene parser knowing them.

#include "stream/GltfAlpha.h"
#include "stream/TriangleSource.h"

#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace penumbra {

/// @brief Everything a factory gets: its JSON parameters (the entry without "type" and
/// "transform"), where they came from for messages (file "scene.json", key path "geometry[2]")
/// and the scene's folder for relative paths.
struct SourceRequest {
    const nlohmann::json& params;
    std::string file;
    std::string path;
    std::filesystem::path baseDir;
    /// A glTF file's alpha ids (GltfAlpha.h), made before the bake; null: MASK materials cast as opaque.
    std::shared_ptr<const GltfAlphaIds> gltfAlpha = nullptr;

    std::string where() const { return path.empty() ? file : file + ": " + path; }
};

using SourceFactory = std::function<TriangleSourcePtr(const SourceRequest&)>;

/// @brief Registers (or replaces) the factory for geometry type @p type.
void registerSourceType(const std::string& type, SourceFactory factory);

/// @brief Opens a source of a registered type.
/// @throw InputError naming `where` when the type is unknown or the parameters are bad.
TriangleSourcePtr openSource(const std::string& type, const SourceRequest& request);

}  // namespace penumbra
