#pragma once
/// @file BakeOutputs.h
/// @brief Where a bake's outputs go, checked before any work: an unwritable `-o`, a stats file
/// that is a directory, or an output that is also an input must stop the bake in its first
/// second, not after an hour of casting. (The files themselves are written through AtomicFile
/// in one OutputSet, so that they appear together or not at all.)

#include "bake/Scene.h"

#include <string>
#include <vector>

namespace penumbra {

/// @brief Checks every output location of a bake of @p scene: the scene's output (which must stay
/// in the scene's directory unless -o named it, Scene.h), @p statsPath, the dump directory
/// @p dumpDir and its files, and @p visibilityPath (any may be empty), and that no two of them,
/// and none of them and an input the scene names (its geometry and points files, the scene file
/// itself), are the same file. The files a receiver kind always names after the output (a
/// camera's PNG, receiverKindDerivedOutputs()) are checked with them; those named after what the
/// scan finds (a lightmap's per-mesh files) once it has run (@p kindFiles), before the cast.
/// @throw InputError naming the output and what is wrong with it.
/// @param directories other folders the bake writes into (checkpoints, shard files): none may
///        share a name with an output.
/// @param kindFiles the files the receiver kind named after the scan (ReceiverKind::outputFiles()),
///        checked with the others once it has run.
void checkBakeOutputs(const SceneDesc& scene, const std::string& statsPath, const std::string& dumpDir,
                      const std::string& visibilityPath = "", const std::vector<std::string>& directories = {},
                      const std::vector<std::string>& kindFiles = {});

/// @brief Refuses an output typed by hand whose folder does not exist: penumbra makes folders only
/// for the scene's own "output" (its out/ beside the scene), never for a path given on the
/// command line or to Result.write(), where a missing folder is far more often a typo (bake,
/// merge, slurm, Python).
/// @throw InputError naming the option, the path and the folder.
void requireOutputFolder(const std::string& option, const std::string& path);

/// @brief Checks one output path against the files the scene reads (checkOutputPath() and the
/// device-and-inode comparison), for commands with a single output (`generate`).
/// @throw InputError naming @p output.
void checkOutputAgainstInputs(const SceneDesc& scene, const std::string& output);

}  // namespace penumbra
