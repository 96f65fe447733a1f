#include "procedural/Generators.h"

#include "procedural/GridGenerator.h"

namespace penumbra {

void registerProceduralGenerators() {
    registerSourceType("grid", [](const SourceRequest& r) { return makeGridSource(parseGridParams(r)); });
}

}  // namespace penumbra
