// NumPy .npy: the whole-file reader, the row reader (compare's dumps) and point receivers.
#include "FuzzSupport.h"

#include "receivers/PointReceivers.h"
#include "stream/Npy.h"

PENUMBRA_FUZZ_FILE("points.npy") {
    using namespace penumbra;
    try {
        NpyArray array = readNpy(path);
        npyAsFloat32(array, path);
    } catch (const InputError&) {
    }
    try {
        NpyRowReader rows(path);
        std::vector<uint8_t> block;
        const uint64_t n = rows.header().shape.empty() ? 0 : rows.header().shape[0];
        for (uint64_t done = 0; done < n; done += 16) rows.next(std::min<uint64_t>(16, n - done), block);
    } catch (const InputError&) {
    }
    loadPointReceivers(path);
}
