#pragma once
/// @file Generators.h
/// @brief Registers every procedural generator as a scene geometry type (SourceRegistry.h):
/// grid, terrain, grass, tree, forest, flowers, scatter, boxes and colonnade.

namespace penumbra {

/// @brief Makes the generators available to scene files. Idempotent.
void registerProceduralGenerators();

}  // namespace penumbra
