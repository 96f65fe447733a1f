// NumPy .npy: the whole-file reader, the row reader (compare's dumps) and point receivers.
#include "FuzzSupport.h"

#include "receivers/PointReceivers.h"
#include "stream/util/Npy.h"

#include <algorithm>

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
        // Rows of zero bytes (shape (10^15, 0)) hold no data: one read of all of them, not a
        // loop as long as the header claims (that loop was a fuzz timeout, not a reader bug).
        const uint64_t step = rows.header().dataBytes == 0 ? std::max<uint64_t>(n, 1) : 16;
        for (uint64_t done = 0; done < n; done += step) rows.next(std::min<uint64_t>(step, n - done), block);
    } catch (const InputError&) {
    }
    loadPointReceivers(path);
}
