// glTF and GLB (the reader tells them apart by content), with buffer files beside the model.
#include "FuzzSupport.h"

#include "stream/GeometryFile.h"

PENUMBRA_FUZZ_FILE("model.glb") { penumbra::fuzz::drain(*penumbra::openGeometryFile(path)); }
