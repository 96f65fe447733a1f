// penumbra's own .ptri triangle streams: header, chunk counts and checksums.
#include "FuzzSupport.h"

#include "stream/GeometryFile.h"

PENUMBRA_FUZZ_FILE("mesh.ptri") { penumbra::fuzz::drain(*penumbra::openGeometryFile(path)); }
