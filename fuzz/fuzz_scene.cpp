// Scene files: parsing and validation of every key, every generator's and receiver kind's
// parameters (the geometry is opened and its first triangles generated), the output checks and,
// when small, the light samples.
#include "FuzzSupport.h"

#include "bake/BakeOutputs.h"
#include "bake/light/Light.h"
#include "bake/kinds/ReceiverKind.h"
#include "bake/Scene.h"
#include "bake/light/SunLight.h"

PENUMBRA_FUZZ_FILE("scene.json") {
    using namespace penumbra;
    SceneDesc scene = loadScene(path);
    checkBakeOutputs(scene, "", "");
    std::unique_ptr<ReceiverKind> kind = makeReceiverKind(scene.receivers, scene);
    (void)kind->passBytes(StreamPass::Scan);
    fuzz::drain(*openSceneGeometry(scene));
    uint64_t positions = 0;
    for (const LightDesc& l : scene.lights) positions += uint64_t(l.samples) * uint64_t(l.sampleSets);
    if (positions <= (1u << 16))
        generateLightSamples(scene.lights, scene.options.groupSize, scene.seed);
}
