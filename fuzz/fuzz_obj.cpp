// Wavefront OBJ, through the public entry point (the reader itself is being rewritten).
#include "FuzzSupport.h"

#include "stream/GeometryFile.h"

PENUMBRA_FUZZ_FILE("mesh.obj") { penumbra::fuzz::drain(*penumbra::openGeometryFile(path)); }
