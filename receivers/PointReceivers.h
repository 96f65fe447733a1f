#pragma once
/// @file PointReceivers.h
/// @brief Point receivers from a file: .npy float32/float64 N x 6 (position, normal) or a CSV with
/// six numeric columns and an optional header line.

#include "receivers/ReceiverSet.h"

#include <string>

namespace penumbra {

/// @throw InputError naming the file and what is wrong (shape, dtype, non-finite value).
ReceiverSet loadPointReceivers(const std::string& path);

}  // namespace penumbra
