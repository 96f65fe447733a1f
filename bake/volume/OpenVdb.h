#pragma once
/// @file OpenVdb.h
/// @brief What the volume receivers share with `penumbra vdb-slice`: OpenVDB's one-time set-up.
/// The slice preview of a written grid is registered from OpenVdb.cpp (bake/output/VolumeSlice.h).
/// Only the files of bake/volume include OpenVDB itself (it compiles slowly, and the CLI loads it
/// as a plugin: stream/util/Plugins.h).

#include <string>

namespace penumbra {

/// @brief openvdb::initialize(), once per process, from any thread.
void initializeOpenVdb();

}  // namespace penumbra
