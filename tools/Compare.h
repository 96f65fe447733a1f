#pragma once
/// @file Compare.h
/// @brief `penumbra compare DUMP_A DUMP_B [--scene SCENE] [--list N] [--mismatches FILE]`:
/// relations, blocked counts and mismatches both ways between two --dump directories of the same
/// receivers, samples and rule. Dumps are read in blocks of receivers, so dumps of millions of
/// receivers (hundreds of MB) are compared in a few MB; `penumbra bench table2` uses this for its
/// mismatch column.

#include "bake/rule/TieClassifier.h"

#include <cstdint>
#include <map>
#include <string>

namespace penumbra {

struct CompareOptions {
    std::string dirA, dirB;
    std::string scenePath;      ///< classify mismatches against this scene's triangles
    uint64_t list = 10;         ///< mismatches printed, with their verdict when a scene is given
    std::string mismatchesCsv;  ///< every mismatch (and its verdict, with a scene), as CSV (optional)
};

struct CompareResult {
    uint64_t receivers = 0, samples = 0, relations = 0;
    uint64_t blockedA = 0, blockedB = 0;
    uint64_t onlyA = 0, onlyB = 0;  ///< blocked in one dump and not the other
    uint64_t ties = 0;              ///< mismatches the blocking rule explains (needs a scene)
    bool classified = false;        ///< ties were counted (a scene was given)
    std::map<std::string, uint64_t> tiesByQuantity;  ///< "edge", "band", "sample_in_plane"
    uint64_t unexplained() const { return onlyA + onlyB - ties; }
};

/// @brief Compares two dumps. With a scene, each mismatch is classified by TieClassifier as a tie
/// of the blocking rule or a real mismatch (TieClassifier.h says exactly when). The first
/// options.list mismatches are printed to stdout, with their verdicts when classified.
/// @throw InputError when a dump is missing, malformed, or the two dumps are not of the same
/// receivers, samples and rule.
CompareResult compareDumps(const CompareOptions& options);

}  // namespace penumbra
