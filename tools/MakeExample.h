#pragma once
/// @file MakeExample.h
/// @brief `penumbra make-example gltf-tree -o FILE.glb`: writes the example files that are made,
/// not stored: a glTF tree whose leaf cards are alpha-tested (MASK) quads with a leaf-cluster
/// texture, for examples/gltf-tree.json. The file is the same bytes on every run.

#include <CLI/CLI.hpp>

#include <string>

namespace penumbra {

struct MakeExampleOptions {
    std::string name;    ///< which example: "gltf-tree"
    std::string output;  ///< the file to write
};

/// @brief Adds the `make-example` subcommand to @p app. @return it, to test whether it was chosen.
CLI::App* addMakeExampleCommand(CLI::App& app, MakeExampleOptions& options);

/// @brief Runs `make-example`. @throw InputError for an unknown example or a failed write.
void runMakeExample(const MakeExampleOptions& options);

/// @brief The glTF tree: an opaque trunk and @p cards instances of one leaf card (a MASK quad with a
/// 128 x 128 texture of five leaves, alphaCutoff 0.5) around a crown, written to @p path.
void writeGltfTree(const std::string& path, int cards = 140);

}  // namespace penumbra
