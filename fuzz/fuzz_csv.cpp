// CSV point lists: the numeric table reader and point receivers.
#include "FuzzSupport.h"

#include "receivers/PointReceivers.h"
#include "stream/Csv.h"

PENUMBRA_FUZZ_FILE("points.csv") {
    using namespace penumbra;
    try {
        readCsvNumbers(path, 0);
    } catch (const InputError&) {
    }
    loadPointReceivers(path);
}
