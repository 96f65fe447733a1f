#include "bake/output/VolumeSlice.h"

#include "stream/util/Error.h"
#include "stream/util/InputFile.h"
#include "stream/util/Plugins.h"

#include <atomic>

namespace penumbra {
namespace {
std::atomic<VolumeSliceWriter> registered{nullptr};
}  // namespace

void registerVolumeSliceWriter(VolumeSliceWriter writer) { registered = writer; }

void writeVolumeSlicePng(const std::string& vdbPath, const std::string& pngPath, const std::string& gridName,
                         char axis, double at, int minWidth) {
    InputScope inputs;  // the VDB is recorded as it is opened: the PNG may not replace it
    if (!registered && !loadPlugin("volume"))
        fail(vdbPath, "reading VDB files needs the volume plugin penumbra_volume.so, which is not in {}", pluginSearchPlaces());
    if (!registered) fail(vdbPath, "the volume plugin did not register its slice writer");
    registered.load()(vdbPath, pngPath, gridName, axis, at, minWidth);
}

}  // namespace penumbra
