// Per-object controls of geometry entries (issue #14): cast_shadows, receive_shadows,
// receiver_offset and max_distance. Each changes a small scene visibly, hpc gives the reference's
// masks bit for bit with it, Embree the same up to classified ties, and bad values are one-line
// errors naming the key.

#include "MethodChecks.h"
#include "TestScenes.h"
#include "TestSupport.h"

#include "bake/Pipeline.h"
#include "bake/Scene.h"
#include "bake/peers/EmbreeCaster.h"
#include "bake/rule/AlphaRule.h"
#include "bake/rule/TieClassifier.h"
#include "procedural/Generators.h"
#include "stream/util/Error.h"
#include "stream/util/Npy.h"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>

using namespace penumbra;
using namespace penumbra::test;

namespace {

using json = nlohmann::json;

json box(glm::vec3 lo, glm::vec3 hi) { return {{lo.x, lo.y, lo.z}, {hi.x, hi.y, hi.z}}; }

/// A "boxes" entry with the per-object keys of @p controls.
json boxes(std::initializer_list<json> list, const json& controls = json::object()) {
    json entry = {{"type", "boxes"}, {"boxes", json(list)}};
    for (const auto& [key, value] : controls.items()) entry[key] = value;
    return entry;
}

/// A flat floor quad of side 6 at y = 0 (a grid without levels), with the keys of @p controls.
json floorEntry(const json& controls = json::object()) {
    json entry = {{"type", "grid"}, {"levels", 0}, {"floor_size", 6}};
    for (const auto& [key, value] : controls.items()) entry[key] = value;
    return entry;
}
const json kLight = {{"type", "rect"}, {"center", {0, 4, 0}}, {"u", {1.5, 0, 0}}, {"v", {0, 0, 1.5}}, {"samples", 64}, {"sample_sets", 4}};

/// A camera looking down at the floor from above and aside.
const json kCamera = {{"type", "camera"}, {"eye", {0.5, 6, 4}}, {"target", {0, 0, 0}}, {"width", 48}, {"height", 36}};

/// A grid of points on the floor, facing up (the same receivers whatever the geometry).
json floorPoints(const ScratchDir& dir) {
    writeFloorPoints(dir.path / "pts.npy", 24, -2.3f, 0.2f);
    return {{"type", "points"}, {"path", "pts.npy"}};
}

SceneDesc sceneOf(const ScratchDir& dir, json geometry, const json& receivers) {
    registerFileSourceTypes();
    registerProceduralGenerators();
    const json scene = {{"geometry", std::move(geometry)}, {"lights", {kLight}}, {"receivers", receivers}, {"output", "out.exr"}};
    return parseScene(scene, (dir.path / "scene.json").string());
}

/// A captured bake of @p scene with @p method: receivers, results and masks; the rule's
/// epsilon length L goes to @p epsilonLength. The stats count the unshadowed receivers.
BakeCapture bake(const SceneDesc& scene, const std::string& method, double* epsilonLength = nullptr) {
    BakeCapture capture;
    capture.wantMasks = method != "penumbra-map";
    BakeSettings settings;
    settings.quiet = true, settings.threads = 2, settings.method = method, settings.capture = &capture;
    const json stats = runBake(scene, settings);
    if (epsilonLength) *epsilonLength = stats["epsilon"]["length"].get<double>();
    const auto& u = capture.receivers.unshadowed;
    CHECK(stats.value("unshadowed_receivers", uint64_t(0)) == uint64_t(std::count(u.begin(), u.end(), uint8_t(1))));
    return capture;
}

size_t shadowed(const BakeCapture& c) {
    size_t n = 0;
    for (float v : c.results.visibility) n += v < 1.0f;
    return n;
}

/// hpc and the reference give the same masks; Embree's differ from them only at classified ties
/// (of the scene's triangles as the bake streams them, with the scene's alpha table).
/// @return hpc's bake.
BakeCapture requireMethodsAgree(const SceneDesc& scene) {
    double length = 1.0;
    BakeCapture hpc = bake(scene, "hpc", &length);
    const BakeCapture reference = bake(scene, "reference"), embree = bake(scene, "embree");
    REQUIRE(hpc.receivers.size() == reference.receivers.size());
    CHECK(hpc.masks.words == reference.masks.words);
    CHECK(hpc.results.visibility == reference.results.visibility);
    TriangleSourcePtr source = openSceneGeometry(scene);
    const std::vector<Triangle> triangles = readAll(*source);
    const TieClassifier classifier(triangles, {scene.options.epsilon, length}, TieClassifier::kDefaultUlps, scene.options.alphaTable);
    uint64_t nonTies = 0;
    const LightSamples& samples = reference.samples;
    for (size_t r = 0; r < reference.receivers.size(); ++r)
        for (int k = 0; k < samples.groupCount(); ++k)
            for (uint64_t d = embree.masks.row(r)[k] ^ reference.masks.row(r)[k]; d; d &= d - 1) {
                const LightSampleGroup& g = samples.groups[k];
                const glm::dvec3 l(samples.position(int(reference.sampleSets[r]), int(g.first) + __builtin_ctzll(d)));
                const RelationVerdict v = classifier.classify(l, samples.w(g.light), glm::dvec3(reference.receivers.position[r]));
                if (!v.tie) ++nonTies, UNSCOPED_INFO(v.describe());
            }
    CHECK(nonTies == 0);
    return hpc;
}

}  // namespace

TEST_CASE("object controls: cast_shadows false keeps the occluder visible but unshadows the floor", "[objects][exactness]") {
    ScratchDir dir("objects");
    const json occluder = box({-0.7f, 1.5f, -0.7f}, {0.7f, 1.7f, 0.7f});
    const SceneDesc casting = sceneOf(dir, {floorEntry(), boxes({occluder})}, kCamera);
    const SceneDesc hidden = sceneOf(dir, {floorEntry(), boxes({occluder}, {{"cast_shadows", false}})}, kCamera);
    const BakeCapture a = requireMethodsAgree(casting), b = requireMethodsAgree(hidden);
    // The camera still sees the occluder: the same receivers, now all unshadowed.
    REQUIRE(a.receivers.size() == b.receivers.size());
    CHECK(a.receivers.position == b.receivers.position);
    CHECK(shadowed(a) > 50);
    CHECK(shadowed(b) == 0);
    // Smooth shading still sees the non-casting faces: the preview's bend table holds them.
    CHECK(b.masks.blockedCount() == 0);
}

TEST_CASE("object controls: receive_shadows false gives unshadowed receivers that still cast", "[objects][exactness]") {
    ScratchDir dir("objects");
    const json low = box({-0.5f, 0.8f, -0.5f}, {0.5f, 1.0f, 0.5f}), high = box({-0.7f, 1.8f, -0.7f}, {0.7f, 2.0f, 0.7f});
    const SceneDesc plain = sceneOf(dir, {floorEntry(), boxes({low}), boxes({high})}, kCamera);
    const SceneDesc noReceive =
        sceneOf(dir, {floorEntry({{"receive_shadows", false}}), boxes({low}), boxes({high})}, kCamera);
    const BakeCapture a = requireMethodsAgree(plain), b = requireMethodsAgree(noReceive);
    REQUIRE(a.receivers.size() == b.receivers.size());
    REQUIRE(b.receivers.unshadowed.size() == b.receivers.size());
    size_t floor = 0, shadowedOthers = 0;
    for (size_t r = 0; r < b.receivers.size(); ++r) {
        const bool onFloor = b.receivers.position[r].y < 0.01f;
        CHECK(b.receivers.isUnshadowed(r) == onFloor);
        if (onFloor) {
            ++floor;
            CHECK(b.results.visibility[r] == 1.0f);
        } else {
            // Every other receiver is shadowed as before: the floor entry still casts.
            CHECK(b.results.visibility[r] == a.results.visibility[r]);
            shadowedOthers += b.results.visibility[r] < 1.0f;
        }
    }
    CHECK(floor > 100);
    CHECK(shadowedOthers > 0);  // the high box shadows the low box's top
    CHECK(shadowed(a) > shadowed(b));

    // Antialiasing: the refinement's sub-pixel receivers know their entry too (the triangle's
    // receiver class), and its cast agrees across methods as the first one does.
    json antialiased = kCamera;
    antialiased["antialias"] = {{"threshold", 0.05}, {"samples", 4}};
    const BakeCapture c = requireMethodsAgree(
        sceneOf(dir, {floorEntry({{"receive_shadows", false}}), boxes({low}), boxes({high})}, antialiased));
    REQUIRE(c.receivers.size() > c.firstPass);
    size_t refinedOnFloor = 0;
    for (size_t r = 0; r < c.receivers.size(); ++r) {
        const bool onFloor = c.receivers.position[r].y < 0.01f;
        CHECK(c.receivers.isUnshadowed(r) == onFloor);
        if (onFloor) CHECK(c.results.visibility[r] == 1.0f);
        refinedOnFloor += onFloor && r >= c.firstPass;
    }
    CHECK(refinedOnFloor > 0);
}

TEST_CASE("object controls: receiver_offset lifts an entry's receivers above a low occluder", "[objects][exactness]") {
    ScratchDir dir("objects");
    const json slab = box({-1, 0.1f, -1}, {1, 0.3f, 1});
    const SceneDesc plain = sceneOf(dir, {floorEntry(), boxes({slab})}, kCamera);
    const SceneDesc lifted = sceneOf(dir, {floorEntry({{"receiver_offset", 0.5}}), boxes({slab})}, kCamera);
    const BakeCapture a = requireMethodsAgree(plain), b = requireMethodsAgree(lifted);
    REQUIRE(a.receivers.size() == b.receivers.size());
    size_t moved = 0;
    for (size_t r = 0; r < a.receivers.size(); ++r) {
        if (std::abs(a.receivers.position[r].y) > 1e-5f) {  // the slab's own receivers stay
            CHECK(b.receivers.position[r] == a.receivers.position[r]);
            continue;
        }
        ++moved;
        CHECK(b.receivers.position[r].y == Approx(0.5f).margin(1e-6));
        CHECK(b.receivers.position[r].x == a.receivers.position[r].x);
        CHECK(b.results.visibility[r] == 1.0f);  // above the slab's top: nothing blocks
    }
    CHECK(moved > 100);
    CHECK(shadowed(a) > shadowed(b));
}

TEST_CASE("object controls: max_distance drops a far occluder's shadow and keeps a near one's", "[objects][exactness]") {
    ScratchDir dir("objects");
    const json points = floorPoints(dir);
    const json nearBox = box({-1.8f, 0.2f, -0.4f}, {-1.0f, 0.5f, 0.4f}), farBox = box({0.6f, 2.0f, -0.5f}, {1.6f, 2.2f, 0.5f});
    const json limit = {{"max_distance", 1.0}};
    const SceneDesc both = sceneOf(dir, {floorEntry(), boxes({nearBox}, limit), boxes({farBox}, limit)}, points);
    const SceneDesc nearOnly = sceneOf(dir, {floorEntry(), boxes({nearBox})}, points);
    const SceneDesc unlimited = sceneOf(dir, {floorEntry(), boxes({nearBox}), boxes({farBox})}, points);
    const BakeCapture limited = requireMethodsAgree(both), expected = bake(nearOnly, "reference"), full = bake(unlimited, "reference");
    CHECK(limited.masks.words == expected.masks.words);  // the near box is within 1, the far one beyond
    CHECK(shadowed(limited) > 20);
    CHECK(shadowed(full) > shadowed(limited));
    // A limit inside the far box's thickness keeps a part of it: still exact.
    const SceneDesc partial = sceneOf(dir, {floorEntry(), boxes({farBox}, {{"max_distance", 2.1}})}, points);
    const BakeCapture p = requireMethodsAgree(partial);
    CHECK(shadowed(p) > 0);
    CHECK(p.masks.blockedCount() < bake(sceneOf(dir, {floorEntry(), boxes({farBox})}, points), "reference").masks.blockedCount());
}

TEST_CASE("object controls: max_distance on random soups, hpc equals the reference in every variant", "[objects][exactness][hpc]") {
    auto table = std::make_shared<AlphaTable>();
    std::vector<uint32_t> ids;
    for (double d : {0.4, 0.9, 1.6, 3.0})
        for (uint32_t a : {0u, uint32_t(kAlphaLeafLower), uint32_t(kAlphaPetalUpper)}) ids.push_back(table->withDistance(a, d));
    std::vector<Triangle> tris = triangleSoup(5, 160, {-2, 0.3f, -2}, {2, 2.5f, 2}, 0.9f);
    Rng rng(9);
    for (Triangle& t : tris)
        if (rng.uniform() < 0.7) t.flags = withAlphaId(t.flags, ids[size_t(rng.uniform() * double(ids.size())) % ids.size()]);
    ReceiverSet receivers = randomReceivers(3, 300, {-2.5f, 0, -2.5f}, {2.5f, 0.5f, 2.5f});
    addReceiversOnTriangles(receivers, everyNth(tris, 8), 4, 3);
    const LightSamples samples = generateLightSamples({rectLight({0.2, 4, 0.1}, {1.5, 0, 0}, {0, 0, 1.5}, 128, 4)}, 64, 7);
    const std::vector<uint32_t> sets = assignSets(receivers, samples.sets);
    const ReceiverEpsilon eps = receiverEpsilonOf(CastOptions());
    const VisibilityMasks reference = castReference(samples, receivers, sets, tris, eps, {}, *table);
    std::vector<Triangle> unlimited = tris;
    for (Triangle& t : unlimited) t.flags = 0;
    const VisibilityMasks opaque = castReference(samples, receivers, sets, unlimited, eps);
    REQUIRE(reference.blockedCount() > 0);
    CHECK(reference.blockedCount() < opaque.blockedCount());
    for (const auto& [name, options] : optionVariants())
        for (int tiles : {1, 3}) {
            INFO(name << ", tiles " << tiles);
            CastOptions o = options;
            o.alphaTable = table;
            CHECK(castHpc(samples, receivers, sets, tris, o, tiles, 97).words == reference.words);
        }
    const VisibilityMasks embree = castEmbree(samples, receivers, sets, tris, eps, nullptr, {}, true, table.get());
    const TieClassifier classifier(tris, eps, TieClassifier::kDefaultUlps, table);
    uint64_t nonTies = 0;
    for (size_t r = 0; r < receivers.size(); ++r)
        for (int k = 0; k < samples.groupCount(); ++k)
            for (uint64_t d = embree.row(r)[k] ^ reference.row(r)[k]; d; d &= d - 1) {
                const LightSampleGroup& g = samples.groups[k];
                const RelationVerdict v = classifier.classify(glm::dvec3(samples.position(int(sets[r]), int(g.first) + __builtin_ctzll(d))),
                                                              samples.w(g.light), glm::dvec3(receivers.position[r]));
                if (!v.tie) ++nonTies, UNSCOPED_INFO(v.describe());
            }
    CHECK(nonTies == 0);
    // ssv tests triangles with a max_distance as cut-outs (issue #17), with the same distance test.
    requireSsvMatchesReference("max_distance soup", {rectLight({0.2, 4, 0.1}, {1.5, 0, 0}, {0, 0, 1.5}, 128, 4)}, receivers, tris,
                               64, eps, table);
}

TEST_CASE("object controls: a hit at the max_distance threshold is a classified tie", "[objects]") {
    auto table = std::make_shared<AlphaTable>();
    // A quad at y = 1 over a receiver at the origin, the sample straight above: the hit is at 1.
    std::vector<Triangle> tris;
    addQuad(tris, {-1, 1, -1}, {1, 1, -1}, {1, 1, 1}, {-1, 1, 1});
    for (Triangle& t : tris) t.flags = withAlphaId(0, table->withDistance(0, 1.0));
    const TieClassifier classifier(tris, receiverEpsilonOf(CastOptions()), TieClassifier::kDefaultUlps, table);
    const RelationVerdict at = classifier.classify({0.1, 3, 0.2}, 1.0, {0.1, 0, 0.2});
    CHECK(at.tie);
    CHECK(at.ruleBlocks);
    auto farther = std::make_shared<AlphaTable>();
    std::vector<Triangle> beyond = tris;
    for (Triangle& t : beyond) t.flags = withAlphaId(0, farther->withDistance(0, 0.99));
    const RelationVerdict past = TieClassifier(beyond, receiverEpsilonOf(CastOptions()), TieClassifier::kDefaultUlps, farther)
                                     .classify({0.1, 3, 0.2}, 1.0, {0.1, 0, 0.2});
    CHECK_FALSE(past.ruleBlocks);
    CHECK_FALSE(past.tie);
}

TEST_CASE("object controls: bad values are one-line errors naming the key", "[objects][scene]") {
    ScratchDir dir("objects");
    const json points = floorPoints(dir);
    auto error = [&](const json& controls) {
        try {
            sceneOf(dir, {floorEntry(), floorEntry(controls)}, points);
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    const std::string wrongType = error({{"cast_shadows", 1}});
    CHECK_THAT(wrongType, Catch::Contains("geometry[1].cast_shadows"));
    CHECK_THAT(error({{"receive_shadows", "no"}}), Catch::Contains("geometry[1].receive_shadows"));
    CHECK_THAT(error({{"receiver_offset", "0.1"}}), Catch::Contains("geometry[1].receiver_offset"));
    CHECK_THAT(error({{"receiver_offset", NAN}}), Catch::Contains("geometry[1].receiver_offset"));
    CHECK_THAT(error({{"max_distance", -1}}), Catch::Contains("geometry[1].max_distance"));
    CHECK_THAT(error({{"max_distance", 0}}), Catch::Contains("geometry[1].max_distance"));
    CHECK_THAT(error({{"max_distance", true}}), Catch::Contains("geometry[1].max_distance"));
    for (const std::string& message : {wrongType, error({{"max_distance", -1}})}) CHECK(message.find('\n') == std::string::npos);
    // Sixteen different (receive_shadows, receiver_offset) pairs do not fit the triangle's 4 bits.
    json many = json::array();
    for (int i = 0; i < 16; ++i) many.push_back(floorEntry({{"receiver_offset", 0.01 * (i + 1)}}));
    CHECK_THROWS_WITH(sceneOf(dir, many, points), Catch::Contains("receiver_offset"));
}

TEST_CASE("object controls: a receiver_offset past the float range is a one-line error, not a crash", "[objects][scene]") {
    // 1e39 is a finite double, so the scene accepts it; the receivers it moves are infinite as
    // floats, which the hierarchy cannot hold (this crashed hpc). Every method refuses it.
    ScratchDir dir("objects");
    for (double offset : {1e39, -1e39, 1e300}) {
        const SceneDesc scene = sceneOf(dir, {floorEntry({{"receiver_offset", offset}}), boxes({box({-1, 1, -1}, {1, 1.2f, 1})})}, kCamera);
        for (const char* method : {"hpc", "reference", "penumbra-map"})
            CHECK_THROWS_WITH(bake(scene, method), Catch::Contains("non-finite position") && Catch::Contains("receiver_offset"));
    }
}

TEST_CASE("object controls: methods without the distance test refuse max_distance", "[objects]") {
    ScratchDir dir("objects");
    const SceneDesc scene = sceneOf(dir, {floorEntry(), boxes({box({-1, 1, -1}, {1, 1.2f, 1})}, {{"max_distance", 2}})}, floorPoints(dir));
    // It names every method that applies it: ssv was left out.
    for (const char* method : {"penumbra-map"})
        CHECK_THROWS_WITH(bake(scene, method), Catch::Contains("max_distance\" of geometry entries (use hpc, reference, embree or ssv)"));
    // cast_shadows is honoured by every method: the approximate penumbra map sees no occluder, and
    // hpc with points receivers (no pass after the bucket pass) never even writes it to a bucket.
    const SceneDesc hidden = sceneOf(dir, {floorEntry(), boxes({box({-1, 1, -1}, {1, 1.2f, 1})}, {{"cast_shadows", false}})}, floorPoints(dir));
    for (const char* method : {"hpc", "reference", "ssv", "penumbra-map"}) CHECK(shadowed(bake(hidden, method)) == 0);
}

TEST_CASE("object controls: penumbra-map under a camera sees cast_shadows false while smooth shading reads every face",
          "[objects][penumbra-map]") {
    // The camera's smooth shading reads the faces in the same pass as the light's view is drawn
    // (side by side), so the no-cast box's faces reach the one and not the other.
    ScratchDir dir("objects");
    auto floorShadowed = [&](bool casts) {
        const SceneDesc scene = sceneOf(dir, {floorEntry(), boxes({box({-1, 1, -1}, {1, 1.2f, 1})}, {{"cast_shadows", casts}})}, kCamera);
        const BakeCapture c = bake(scene, "penumbra-map");
        size_t floor = 0, shadowed = 0;
        for (size_t r = 0; r < c.receivers.size(); ++r)
            if (std::abs(c.receivers.position[r].y) < 1e-3f) ++floor, shadowed += c.results.visibility[r] < 1.0f;
        REQUIRE(floor > 100);
        return shadowed;
    };
    CHECK(floorShadowed(false) == 0);
    CHECK(floorShadowed(true) > 50);
}

TEST_CASE("object controls: vertex and lightmap receivers take their entry's receive_shadows and receiver_offset",
          "[objects][vertices][lightmap]") {
    ScratchDir dir("objects");
    AllowOutsidePaths examples;
    const std::string source = std::string(PENUMBRA_SOURCE_DIR) + "/examples/";
    auto entry = [&](const std::string& type, const std::string& file, const json& controls) {
        json e = {{"type", type}, {"path", source + file}};
        for (const auto& [key, value] : controls.items()) e[key] = value;
        return e;
    };
    const json occluder = boxes({box({-0.6f, 1.0f, -0.6f}, {0.6f, 1.2f, 0.6f})});
    const json vertices = {{"type", "vertices"}, {"meshes", {0}}};
    auto vertexScene = [&](const json& controls) {
        registerFileSourceTypes();
        registerProceduralGenerators();
        const json scene = {{"geometry", {entry("glb", "vertices-floor.glb", controls), occluder}},
                            {"lights", {kLight}}, {"receivers", vertices}, {"output", "out.glb"}};
        return parseScene(scene, (dir.path / "scene.json").string());
    };
    const BakeCapture a = bake(vertexScene(json::object()), "hpc");
    const BakeCapture b = requireMethodsAgree(vertexScene({{"receive_shadows", false}, {"receiver_offset", 0.05}}));
    REQUIRE(a.receivers.size() == b.receivers.size());
    CHECK(shadowed(a) > 0);
    CHECK(shadowed(b) == 0);
    for (size_t r = 0; r < a.receivers.size(); ++r) {
        CHECK(b.receivers.isUnshadowed(r));
        const glm::vec3 moved = glm::vec3(glm::dvec3(a.receivers.position[r]) + 0.05 * glm::dvec3(a.receivers.normal[r]));
        CHECK(b.receivers.position[r] == moved);
    }

    // A lightmap atlas of two meshes: the blockers' texels are unshadowed, the room's lifted.
    auto lightmapScene = [&](const json& room, const json& blockers) {
        const json scene = {{"geometry", {entry("obj", "room.obj", room), entry("obj", "room-blockers.obj", blockers)}},
                            {"lights", {{{"type", "rect"}, {"center", {2.2, 4.0, 1.8}}, {"u", {1.5, 0, 0}}, {"v", {0, 0, 1.5}}, {"samples", 64}}}},
                            {"receivers", {{"type", "lightmap"}, {"meshes", {0, 1}}, {"uv", "generate"}, {"resolution", 48}, {"padding", 1}}},
                            {"output", "out.exr"}};
        return parseScene(scene, (dir.path / "scene.json").string());
    };
    const BakeCapture plain = bake(lightmapScene(json::object(), json::object()), "hpc");
    const BakeCapture mixed = requireMethodsAgree(lightmapScene({{"receiver_offset", 0.01}}, {{"receive_shadows", false}}));
    REQUIRE(plain.receivers.size() == mixed.receivers.size());
    size_t unshadowed = 0, lifted = 0;
    for (size_t r = 0; r < plain.receivers.size(); ++r) {
        if (mixed.receivers.isUnshadowed(r)) {
            ++unshadowed;
            CHECK(mixed.receivers.position[r] == plain.receivers.position[r]);
            CHECK(mixed.results.visibility[r] == 1.0f);
        } else {
            ++lifted;
            CHECK(glm::length(glm::dvec3(mixed.receivers.position[r]) - glm::dvec3(plain.receivers.position[r])) ==
                  Approx(0.01).epsilon(1e-3));
        }
    }
    CHECK(unshadowed > 0);
    CHECK(lifted > unshadowed);
}

TEST_CASE("object controls: an export keeps cast_shadows, not the scene's receiver classes and distance ids", "[objects][scene]") {
    ScratchDir dir("objects");
    const SceneDesc scene = sceneOf(dir,
                                    {floorEntry({{"receive_shadows", false}, {"receiver_offset", 0.1}}),
                                     boxes({box({-1, 1, -1}, {1, 1.2f, 1})}, {{"cast_shadows", false}, {"max_distance", 2}})},
                                    floorPoints(dir));
    TriangleSourcePtr baked = openSceneGeometry(scene), exported = openSceneGeometryForExport(scene);
    const std::vector<Triangle> a = readAll(*baked), b = readAll(*exported);
    REQUIRE(a.size() == 14);
    REQUIRE(b.size() == a.size());
    for (size_t i = 0; i < a.size(); ++i) {
        const bool box = i >= 2;
        CHECK(receiverClassOf(a[i].flags) == (box ? 0u : 1u));
        CHECK(bool(a[i].flags & kTriangleNoCast) == box);
        CHECK((alphaIdOf(a[i].flags) != 0) == box);
        CHECK(scene.options.alphaTable->maxDistance(alphaIdOf(a[i].flags)) == (box ? 2.0 : INFINITY));
        CHECK(b[i].flags == (box ? uint32_t(kTriangleNoCast) | kTriangleClosed | (i == 2 ? kTriangleSolidStart : 0u) : 0u));
    }
}
