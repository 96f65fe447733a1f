#include "bake/volume/OpenVdb.h"

#include "bake/LibraryErrors.h"
#include "bake/output/ImageWriters.h"
#include "bake/output/VolumeSlice.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/InputFile.h"

#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <mutex>
#include <vector>

namespace penumbra {

void initializeOpenVdb() {
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });
}

void stampContentUuid(const std::string& path) {
    // Header (openvdb/io/Archive.cc, file version 212 and later): int64 magic, uint32 file
    // version, uint32 library major and minor, one byte "has grid offsets", then the UUID as 36
    // ASCII characters.
    constexpr std::streamoff kUuidAt = 21, kUuidSize = 36;
    std::fstream file(path, std::ios::in | std::ios::out | std::ios::binary);
    if (!file) fail(path, "cannot reopen the VDB file to finish its header");
    char header[kUuidAt + kUuidSize];
    if (!file.read(header, sizeof header)) return;  // shorter than any header: not ours to touch
    int64_t magic;
    uint32_t version;
    std::memcpy(&magic, header, sizeof magic), std::memcpy(&version, header + 8, sizeof version);
    auto uuidShaped = [&] {
        for (int i = 0; i < kUuidSize; ++i) {
            const char c = header[kUuidAt + i];
            if (i == 8 || i == 13 || i == 18 || i == 23 ? c != '-' : !std::isxdigit(static_cast<unsigned char>(c))) return false;
        }
        return true;
    };
    if (magic != openvdb::OPENVDB_MAGIC || version < 212 || !uuidShaped()) return;
    // Two FNV-1a hashes of every byte but the UUID's (the header before it, then the grids).
    uint64_t h[2] = {0xcbf29ce484222325ull, 0x84222325cbf29ce4ull};
    auto hash = [&](const char* data, std::streamsize n) {
        for (std::streamsize i = 0; i < n; ++i)
            for (uint64_t& x : h) x = (x ^ static_cast<unsigned char>(data[i])) * 0x100000001b3ull;
    };
    hash(header, kUuidAt);
    std::vector<char> block(size_t(1) << 20);
    while (file.read(block.data(), std::streamsize(block.size())) || file.gcount() > 0) hash(block.data(), file.gcount());
    // Version 8 (RFC 9562, custom), variant 10.
    const std::string hex = fmt::format("{:016x}{:016x}", h[0], h[1]);
    std::string uuid = hex.substr(0, 8) + "-" + hex.substr(8, 4) + "-8" + hex.substr(13, 3) + "-" +
                       "89ab"[hex[16] % 4] + hex.substr(17, 3) + "-" + hex.substr(20, 12);
    file.clear();
    file.seekp(kUuidAt);
    if (!file.write(uuid.data(), kUuidSize) || !file.flush()) fail(path, "cannot rewrite the VDB file's header");
}

namespace {

/// io::File's format written to a stream of ours: Archive's writer with grid offsets (seekable),
/// which io::File calls on an ofstream whose state it never looks at.
class CheckedArchive : public openvdb::io::Archive {
public:
    void writeTo(std::ostream& os, const openvdb::GridPtrVec& grids) const { write(os, grids, /*seekable=*/true); }
};

}  // namespace

void writeVdbFile(const std::string& path, const std::string& output, const openvdb::GridPtrVec& grids) {
    std::ofstream os(path, std::ios::binary | std::ios::trunc);
    if (!os) fail(output, "cannot create file: {}", std::strerror(errno));
    os.exceptions(std::ios::badbit | std::ios::failbit);  // the first failed write throws, errno still its
    try {
        errno = 0;
        CheckedArchive().writeTo(os, grids);
        os.close();
    } catch (const std::ios_base::failure&) {
        const int error = errno;
        fail(output, "write failed: {}", error ? std::strerror(error) : "the stream failed (a full disk, or a file size limit)");
    } catch (const openvdb::Exception& e) {
        fail(output, "OpenVDB could not write the file: {}", e.what());
    }
}

namespace {

/// Grid @p gridName of the VDB file @p vdbPath. OpenVDB reads through a stream that throws at the
/// first read it cannot complete: io::File went on past the end of a truncated file, took
/// whatever its length fields then held, and filled strings of gigabytes (14 GB of RSS for one
/// cut file before any error).
openvdb::FloatGrid::Ptr readFloatGrid(const std::string& vdbPath, const std::string& gridName) {
    checkInputFile(vdbPath);  // a regular file, and recorded: the slice's PNG may not replace it
    std::ifstream in(vdbPath, std::ios::binary);
    if (!in) fail(vdbPath, "cannot open: {}", std::strerror(errno));
    in.exceptions(std::ios::failbit | std::ios::badbit);
    openvdb::GridPtrVecPtr grids;
    try {
        grids = openvdb::io::Stream(in, false).getGrids();
    } catch (const std::ios_base::failure&) {
        fail(vdbPath, "not a complete VDB file: it ends, or cannot be read, before its grids do (truncated or damaged)");
    } catch (const std::bad_alloc&) {  // a damaged length field: the read asked for more than any memory
        fail(vdbPath, "a size read from the file does not fit in memory (a damaged VDB, or grids larger than this machine holds)");
    } catch (const std::length_error&) {
        fail(vdbPath, "a size read from the file is beyond what a container holds (a damaged VDB)");
    } catch (const openvdb::Exception& e) {
        fail(vdbPath, "OpenVDB could not read the file: {}", e.what());
    }
    openvdb::GridBase::Ptr named;
    for (const openvdb::GridBase::Ptr& g : grids ? *grids : openvdb::GridPtrVec())
        if (g && g->getName() == gridName) named = g;
    if (!named) fail(vdbPath, "no grid named \"{}\"", gridName);
    openvdb::FloatGrid::Ptr grid = openvdb::gridPtrCast<openvdb::FloatGrid>(named);
    if (!grid) fail(vdbPath, "grid \"{}\" is not a float grid", gridName);
    return grid;
}

void writeOpenVdbSlicePng(const std::string& vdbPath, const std::string& pngPath, const std::string& gridName,
                          char axis, double at, int minWidth) {
    initializeOpenVdb();
    if (axis != 'x' && axis != 'y' && axis != 'z') fail(vdbPath, "slice axis must be x, y or z (got '{}')", axis);
    const openvdb::FloatGrid::Ptr grid = readFloatGrid(vdbPath, gridName);
    openvdb::CoordBBox bounds = grid->evalActiveVoxelBoundingBox();
    auto lo = grid->getMetadata<openvdb::Vec3IMetadata>("penumbra_min");
    auto hi = grid->getMetadata<openvdb::Vec3IMetadata>("penumbra_max");
    if (lo && hi) bounds = openvdb::CoordBBox(openvdb::Coord(lo->value()), openvdb::Coord(hi->value()));
    if (bounds.empty()) fail(vdbPath, "grid \"{}\" is empty", gridName);

    const int a = axis - 'x';
    if (!std::isfinite(at)) fail("--at", "must be a finite number, got {}", at);
    openvdb::Vec3d probe(0.0);
    probe[a] = at;
    // Compared in double: a far coordinate must not wrap into the grid's index range.
    const double index = std::round(grid->transform().worldToIndex(probe)[a]);
    if (!(index >= bounds.min()[a] && index <= bounds.max()[a]))
        fail(vdbPath, "{} = {} lies outside the grid (index {:.0f}, grid {}..{})", axis, at, index, bounds.min()[a],
             bounds.max()[a]);
    const int slice = int(index);
    // (right, down) axes of the image and whether rows run from the axis's high end.
    const int u = axis == 'x' ? 2 : 0, v = axis == 'y' ? 2 : 1;
    const bool flip = axis != 'y';  // y up for x and z slices; z down when seen from above
    const int w = bounds.max()[u] - bounds.min()[u] + 1, h = bounds.max()[v] - bounds.min()[v] + 1;
    const int scale = std::max(1, std::min((minWidth + w - 1) / w, 8192 / std::max(w, h)));
    std::vector<uint8_t> pixels(size_t(w) * scale * h * scale);
    auto acc = grid->getConstAccessor();
    for (int row = 0; row < h * scale; ++row)
        for (int col = 0; col < w * scale; ++col) {
            openvdb::Coord c;
            c[a] = slice;
            c[u] = bounds.min()[u] + col / scale;
            c[v] = flip ? bounds.max()[v] - row / scale : bounds.min()[v] + row / scale;
            pixels[size_t(row) * w * scale + col] = encodeSrgb(acc.getValue(c));
        }
    ensureParentDirectory(pngPath);
    writePng8(pngPath, w * scale, h * scale, 1, pixels);
}


/// Registers what this plugin adds when it is linked in or loaded: the slice writer, and
/// OpenVDB's exceptions as library errors (one line naming the file, exit 1).
const bool kRegistered = [] {
    registerVolumeSliceWriter(&writeOpenVdbSlicePng);
    registerLibraryErrorType([](const std::exception& e) { return dynamic_cast<const openvdb::Exception*>(&e) != nullptr; });
    return true;
}();

}  // namespace

}  // namespace penumbra
