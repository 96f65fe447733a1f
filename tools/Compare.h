#pragma once
/// @file Compare.h
/// @brief `penumbra compare DUMP_A DUMP_B [--scene SCENE]`: relations, blocked counts and
/// mismatches both ways between two --dump directories of the same receivers and samples.
/// Dumps are read in blocks of receivers, so dumps of millions of receivers (hundreds of MB)
/// are compared in a few MB; `penumbra bench table2` uses this for its mismatch column.

#include <cstdint>
#include <string>

namespace penumbra {

struct CompareResult {
    uint64_t receivers = 0, samples = 0, relations = 0;
    uint64_t blockedA = 0, blockedB = 0;
    uint64_t onlyA = 0, onlyB = 0;  ///< blocked in one dump and not the other
    uint64_t ties = 0;              ///< mismatches the blocking rule explains (needs a scene)
    bool classified = false;        ///< ties were counted (a scene was given)
    uint64_t unexplained() const { return onlyA + onlyB - ties; }
};

/// @brief Compares two dumps; with @p scenePath, mismatches are classified as ties or not.
///
/// A mismatch is a tie when isTie() (tolerance 1e-4) holds for a scene triangle whose box,
/// grown by that tolerance and twice eps(r), the segment from receiver to sample meets: only a
/// triangle near the segment can be what one method found and the other did not. The scene's
/// triangles are held in memory (with a bounding-volume hierarchy) only when classifying.
/// @throw InputError when a dump is missing, malformed, or the two dumps are not of the same
/// receivers and samples.
CompareResult compareDumps(const std::string& dirA, const std::string& dirB, const std::string& scenePath);

}  // namespace penumbra
