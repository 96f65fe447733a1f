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

/// @brief Replaces the random UUID that OpenVDB writes into every file's header with one made from
/// a hash of the rest of the file, so the same grids give the same bytes (penumbra's outputs are
/// byte-identical for any thread count, tiling or shard count; OpenVDB offers no way to set it).
/// The UUID stays unique per content, which is all OpenVDB's readers use it for. A file whose
/// header is not the layout this expects (a future OpenVDB) is left as it is.
/// @param path a .vdb file just written by openvdb::io::File, not yet published
/// @throw InputError naming @p path when it cannot be read back or rewritten
void stampContentUuid(const std::string& path);

}  // namespace penumbra
