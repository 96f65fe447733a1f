#pragma once
/// @file PointReceivers.h
/// @brief Point receivers from a file: .npy float32/float64 N x 6 (position, normal) or a CSV with
/// six numeric columns and an optional header line.

#include "receivers/ReceiverSet.h"

#include <cstdint>
#include <optional>
#include <string>

namespace penumbra {

/// @throw InputError naming the file and what is wrong (shape, dtype, non-finite value).
ReceiverSet loadPointReceivers(const std::string& path);

/// @brief The receiver count of a .npy point file, from its header alone: N for an N x 6 array.
/// Nullopt for a CSV (its lines tell) and for any file loadPointReceivers() would refuse, which
/// then names what is wrong; so a malformed header never reaches the memory plan as a count.
std::optional<uint64_t> pointReceiverBound(const std::string& path);

}  // namespace penumbra
