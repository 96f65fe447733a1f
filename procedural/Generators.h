#pragma once
/// @file Generators.h
/// @brief Registers every procedural generator as a scene geometry type (SourceRegistry.h).

namespace penumbra {

/// @brief Makes "grid" (and the other generators) available to scene files. Idempotent.
void registerProceduralGenerators();

}  // namespace penumbra
