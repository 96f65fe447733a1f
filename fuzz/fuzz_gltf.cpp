// glTF and GLB (the reader tells them apart by content), with buffer files beside the model; the
// MASK materials' textures are planned, decoded and given ids as a bake does (stream/GltfAlpha.h).
#include "FuzzSupport.h"

#include "stream/GeometryFile.h"
#include "stream/GltfAlpha.h"

#include <cmath>

PENUMBRA_FUZZ_FILE("model.glb") {
    penumbra::fuzz::drain(*penumbra::openGeometryFile(path));
    const penumbra::GltfDocument doc = penumbra::loadGltfDocument(path);
    if (penumbra::planGltfAlpha(doc).empty()) return;
    penumbra::AlphaTable table;
    auto ids = penumbra::buildGltfAlpha(doc, table, INFINITY);
    penumbra::fuzz::drain(*penumbra::openGeometryFile(path, penumbra::GeometryFormat::Gltf, {}, ids));
}
