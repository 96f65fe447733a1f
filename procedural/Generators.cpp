#include "procedural/Generators.h"

#include "procedural/BoxesGenerator.h"
#include "procedural/FlowerGenerator.h"
#include "procedural/GrassGenerator.h"
#include "procedural/GridGenerator.h"
#include "procedural/ScatterGenerator.h"
#include "procedural/TerrainGenerator.h"
#include "procedural/TreeGenerator.h"

namespace penumbra {

void registerProceduralGenerators() {
    registerSourceType("grid", [](const SourceRequest& r) { return makeGridSource(parseGridParams(r)); });
    registerSourceType("terrain", [](const SourceRequest& r) { return makeTerrainSource(parseTerrainParams(r)); });
    registerSourceType("grass", [](const SourceRequest& r) { return makeGrassSource(parseGrassParams(r)); });
    registerSourceType("tree", [](const SourceRequest& r) { return makeTreeSource(parseTreeParams(r)); });
    registerSourceType("forest", [](const SourceRequest& r) { return makeForestSource(parseForestParams(r)); });
    registerSourceType("flowers", [](const SourceRequest& r) { return makeFlowerSource(parseFlowerParams(r)); });
    registerSourceType("scatter", [](const SourceRequest& r) { return openScatterSource(r); });
    registerSourceType("boxes", [](const SourceRequest& r) { return makeBoxSource(parseBoxes(r)); });
    registerSourceType("colonnade", [](const SourceRequest& r) { return makeBoxSource(colonnadeBoxes(parseColonnadeParams(r)), "colonnade"); });
}

}  // namespace penumbra
