#pragma once
/// @file OpenVdb.h
/// @brief What the volume receivers share with `penumbra vdb-slice`: OpenVDB's one-time set-up,
/// and writing a .vdb deterministically and checked.
/// The slice preview of a written grid is registered from OpenVdb.cpp (bake/output/VolumeSlice.h).
/// Only the files of bake/volume include OpenVDB itself (it compiles slowly, and the CLI loads it
/// as a plugin: stream/util/Plugins.h).

#include <openvdb/Grid.h>

#include <string>

namespace penumbra {

/// @brief openvdb::initialize(), once per process, from any thread.
void initializeOpenVdb();

/// @brief Replaces the random UUID that OpenVDB writes into every file's header with one made from
/// a hash of the rest of the file, so the same grids give the same bytes (penumbra's outputs are
/// byte-identical for any thread count, tiling or shard count; OpenVDB offers no way to set it).
/// The UUID stays unique per content, which is all OpenVDB's readers use it for. A file whose
/// header is not the layout this expects (a future OpenVDB) is left as it is.
/// @param path a .vdb file just written by writeVdbFile(), not yet published
/// @throw InputError naming @p path when it cannot be read back or rewritten
void stampContentUuid(const std::string& path);

/// @brief Writes @p grids in OpenVDB's file format (with grid offsets, as io::File writes it) to
/// @p path, checking every write: io::File writes through a stream it never checks, so a full
/// disk left a truncated .vdb and exit 0.
/// @param output the output the file becomes, for messages
/// @throw InputError naming @p output when a write fails (full disk, file size limit)
void writeVdbFile(const std::string& path, const std::string& output, const openvdb::GridPtrVec& grids);

}  // namespace penumbra
