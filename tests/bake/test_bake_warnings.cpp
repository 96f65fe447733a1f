// bakeWarnings(): lights whose float32 samples cannot stratify them, and lights that face away.

#include "bake/BakeWarnings.h"

#include <catch2/catch.hpp>

#include <algorithm>

using namespace penumbra;

namespace {

ReceiverSet oneFloorReceiver() {
    ReceiverSet set;
    set.position.push_back({0, 0, 0});
    set.normal.push_back({0, 1, 0});
    return set;
}

LightDesc downwardRect(glm::dvec3 center, double size) {
    LightDesc light;
    light.center = center;
    light.u = {size, 0, 0}, light.v = {0, 0, size};  // u x v = -y: emits downwards
    light.where = "scene.json: lights[0]";
    return light;
}

std::vector<std::string> warningsFor(const LightDesc& light) {
    return bakeWarnings(nlohmann::json{{"type", "camera"}}, oneFloorReceiver(), {light});
}

}  // namespace

TEST_CASE("warnings: a light whose float samples are coarser than its strata", "[warnings]") {
    // 3e9 from the origin floats are 256 apart; a 2.5-wide light's 256 samples are 0.16 apart.
    const std::vector<std::string> far = warningsFor(downwardRect({3e9, 6, 0.5}, 2.5));
    REQUIRE(far.size() == 1);
    CHECK_THAT(far[0], Catch::StartsWith("scene.json: lights[0]: its 256 samples are float32") && Catch::Contains(" 256 apart") &&
                           Catch::Contains("3e+09 from the origin") && Catch::Contains("move the scene nearer the origin"));
    // The same light near the origin, and a small light at a moderate distance, are fine.
    CHECK(warningsFor(downwardRect({0.5, 6, 0.5}, 2.5)).empty());
    CHECK(warningsFor(downwardRect({1e4, 6, 0.5}, 0.1)).empty());
    // A thin rect is judged by its narrow side: 1e4 away floats are 0.001 apart.
    LightDesc thin = downwardRect({1e4, 6, 0.5}, 100.0);
    thin.v = {0, 0, 0.004};
    CHECK(warningsFor(thin).size() == 1);
}

TEST_CASE("warnings: a sun narrower than float directions can resolve", "[warnings]") {
    LightDesc sun;
    sun.type = LightType::Sun;
    sun.direction = {0.3, -1, 0.2};
    sun.where = "scene.json: lights[0]";
    CHECK(warningsFor(sun).empty());  // 0.53 degrees
    sun.angularDiameterDeg = 1e-5;
    const std::vector<std::string> narrow = warningsFor(sun);
    REQUIRE(narrow.size() == 1);
    CHECK_THAT(narrow[0], Catch::Contains("as unit directions") && Catch::Contains("widen its angular_diameter_deg"));
}

TEST_CASE("warnings: a planar light facing away from every receiver", "[warnings]") {
    LightDesc up = downwardRect({0, 4, 0}, 1.0);
    std::swap(up.u, up.v);
    const std::vector<std::string> away = warningsFor(up);
    REQUIRE(away.size() == 1);
    CHECK_THAT(away[0], Catch::Contains("faces away from every receiver") && Catch::Contains("swap \"u\" and \"v\""));
}

TEST_CASE("warnings: a polygon light is judged by its own plane, not one through the origin", "[warnings]") {
    // Over a floor receiver at y = 0.5, at y = 4: emitting downwards lights it, upwards does not.
    ReceiverSet floor;
    floor.position.push_back({0, 0.5f, 0});
    floor.normal.push_back({0, 1, 0});
    LightDesc down;
    down.type = LightType::Polygon;
    down.polygon = {{-1, 4, -1}, {1, 4, -1}, {1, 4, 1}, {-1, 4, 1}};
    down.where = "scene.json: lights[0]";
    REQUIRE(down.emitterNormal().y < 0);
    CHECK(bakeWarnings(nlohmann::json{{"type", "points"}}, floor, {down}).empty());
    LightDesc up = down;
    std::reverse(up.polygon.begin(), up.polygon.end());
    const std::vector<std::string> away = bakeWarnings(nlohmann::json{{"type", "points"}}, floor, {up});
    REQUIRE(away.size() == 1);
    CHECK_THAT(away[0], Catch::Contains("lights[0]: faces away from every receiver") && Catch::Contains("\"vertices\""));
}

TEST_CASE("warnings: a sun travelling away from every receiver's surface", "[warnings]") {
    LightDesc sun;
    sun.type = LightType::Sun;
    sun.where = "scene.json: lights[0]";
    sun.direction = {0, -1, 0};  // down onto the floor: lit
    CHECK(warningsFor(sun).empty());
    sun.direction = {1, -0.001, 0};  // grazing, its disk partly above the horizon: lit
    CHECK(warningsFor(sun).empty());
    sun.direction = {0, 1, 0};  // up, away from the floor's surface
    const std::vector<std::string> away = warningsFor(sun);
    REQUIRE(away.size() == 1);
    CHECK_THAT(away[0], Catch::Contains("lights[0]: travels away from every receiver's surface") && Catch::Contains("negate"));
    sun.direction = {1, 0.001, 0};  // just below the horizon, but its disk (0.53 degrees) reaches above it
    CHECK(warningsFor(sun).empty());
}

TEST_CASE("warnings: a receiver epsilon that is a large part of the receivers' extent", "[warnings]") {
    // A 5 m patch of receivers at 1e6: eps = 1e-5 x 1e6 = 10 m, twice the patch, so every
    // contact shadow is lost (a bunny there baked with no shadow at all, and no word).
    ReceiverSet far;
    for (float d : {0.0f, 5.0f}) far.position.push_back({1e6f + d, 0, 0}), far.normal.push_back({0, 1, 0});
    const auto warning = epsilonWarning(far, 1e-5, 1e6 + 5);
    REQUIRE(warning);
    CHECK_THAT(*warning, Catch::Contains("receiver epsilon is 10") && Catch::Contains("lower bake.epsilon"));
    // At the origin, or with a small enough epsilon, or one receiver alone: nothing.
    ReceiverSet near;
    for (float d : {0.0f, 5.0f}) near.position.push_back({d, 0, 0}), near.normal.push_back({0, 1, 0});
    CHECK_FALSE(epsilonWarning(near, 1e-5, 5));
    CHECK_FALSE(epsilonWarning(far, 1e-9, 1e6 + 5));
    CHECK_FALSE(epsilonWarning(far, 0, 1e6 + 5));
    CHECK_FALSE(epsilonWarning(oneFloorReceiver(), 1e-5, 1e6));
}
