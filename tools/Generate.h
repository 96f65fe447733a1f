#pragma once
/// @file Generate.h
/// @brief `penumbra generate SCENE.json -o OUT.(ptri|obj|glb|gltf) [--threads N]`: writes a
/// scene's geometry — generated and loaded, with transforms applied, in scene order — to a file,
/// so that other tools see exactly the triangles a bake sees.

#include <CLI/CLI.hpp>

#include <cstdint>
#include <string>

namespace penumbra {

struct GenerateOptions {
    std::string scene;   ///< scene file (JSON)
    std::string output;  ///< destination; the format follows the extension (GeometryFile.h)
    int threads = 0;     ///< worker threads, 0 for all cores; the bytes written do not depend on it
    bool quiet = false;
};

/// @brief Adds the `generate` subcommand to @p app, parsing into @p options (which must outlive
/// the parse). @return the subcommand, to test whether it was chosen.
CLI::App* addGenerateCommand(CLI::App& app, GenerateOptions& options);

/// @brief Runs `generate`. @return the number of triangles written.
/// @throw InputError for a bad scene, a bad --threads, or a failed write (no partial file remains).
uint64_t runGenerate(const GenerateOptions& options);

}  // namespace penumbra
