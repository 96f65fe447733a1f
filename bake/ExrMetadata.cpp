#include "bake/ExrMetadata.h"

#include "bake/Scene.h"

#include <glm/geometric.hpp>

#include <sys/stat.h>

#include <array>
#include <cerrno>
#include <climits>
#include <cstdlib>
#include <ctime>
#include <optional>

#ifndef PENUMBRA_VERSION
#define PENUMBRA_VERSION "unknown"
#endif

namespace penumbra {
namespace {

/// SOURCE_DATE_EPOCH (the reproducible-builds convention), else the scene file's mtime.
std::optional<std::time_t> captureTime(const std::string& sceneFile) {
    if (const char* epoch = std::getenv("SOURCE_DATE_EPOCH")) {
        char* end = nullptr;
        errno = 0;
        const long long t = std::strtoll(epoch, &end, 10);
        if (errno == 0 && end != epoch && *end == '\0' && t >= 0) return std::time_t(t);
    }
    struct stat st {};
    if (!sceneFile.empty() && ::stat(sceneFile.c_str(), &st) == 0) return st.st_mtime;
    return std::nullopt;
}

glm::vec3 f3(const glm::dvec3& v) { return glm::vec3(v); }

/// The area centroid of a planar polygon (its fan triangles' centroids weighted by area).
glm::dvec3 polygonCentroid(const std::vector<glm::dvec3>& p) {
    glm::dvec3 sum(0.0), mean(0.0);
    double area = 0;
    for (const glm::dvec3& v : p) mean += v / double(p.size());
    for (size_t i = 1; i + 1 < p.size(); ++i) {
        const double a = glm::length(glm::cross(p[i] - p[0], p[i + 1] - p[0]));
        sum += a * (p[0] + p[i] + p[i + 1]) / 3.0, area += a;
    }
    return area > 0 ? sum / area : mean;
}

void addLight(std::vector<ExrAttribute>& out, size_t index, const LightDesc& l) {
    static const char* typeNames[] = {"rect", "disk", "sphere", "polygon", "sun"};
    const std::string key = "penumbra:light" + std::to_string(index) + ".";
    out.push_back({key + "type", std::string(typeNames[int(l.type)])});
    out.push_back({key + "samples", l.samples});
    out.push_back({key + "sampleSets", l.sampleSets});
    if (l.type == LightType::Sun) {
        out.push_back({key + "direction", f3(l.direction)});
        out.push_back({key + "angularDiameterDeg", float(l.angularDiameterDeg)});
        out.push_back({key + "irradiance", f3(l.irradiance)});
        return;
    }
    out.push_back({key + "center", f3(l.type == LightType::Polygon ? polygonCentroid(l.polygon) : l.center)});
    if (l.type == LightType::Rect) out.push_back({key + "u", f3(l.u)}), out.push_back({key + "v", f3(l.v)});
    if (l.type == LightType::Disk) out.push_back({key + "normal", f3(l.normal)});
    if (l.type == LightType::Disk || l.type == LightType::Sphere) out.push_back({key + "radius", float(l.radius)});
    if (l.type == LightType::Polygon) {
        std::vector<float> xyz;
        for (const glm::dvec3& v : l.polygon) xyz.insert(xyz.end(), {float(v.x), float(v.y), float(v.z)});
        out.push_back({key + "vertices", xyz});
    }
    out.push_back({key + "area", float(l.area())});
    out.push_back({key + "radiance", f3(l.radiance)});
}

}  // namespace

std::vector<ExrAttribute> bakeAttributes(const SceneDesc& scene, const LightSamples& samples, ExrColour colour) {
    std::vector<ExrAttribute> a = {{"software", std::string("penumbra " PENUMBRA_VERSION)}};
    if (const std::optional<std::time_t> t = captureTime(scene.file)) {
        std::tm utc{};
        gmtime_r(&*t, &utc);
        char date[32];
        std::strftime(date, sizeof date, "%Y:%m:%d %H:%M:%S", &utc);
        a.push_back({"capDate", std::string(date)});
        a.push_back({"utcOffset", 0.0f});
    }
    a.push_back({"penumbra:lights", int(scene.lights.size())});
    a.push_back({"penumbra:samples", samples.sampleCount});
    a.push_back({"penumbra:sampleSets", samples.sets});
    a.push_back({"penumbra:groupSize", scene.options.groupSize});
    if (scene.seed <= uint64_t(INT_MAX)) a.push_back({"penumbra:seed", int(scene.seed)});
    else a.push_back({"penumbra:seed", std::to_string(scene.seed)});
    a.push_back({"penumbra:epsilon", float(scene.options.epsilon)});
    a.push_back({"penumbra:rgb", std::string(colour == ExrColour::Visibility ? "visibility" : "irradiance")});
    for (size_t i = 0; i < scene.lights.size(); ++i) addLight(a, i, scene.lights[i]);
    return a;
}

namespace {

using Rows = std::array<std::array<double, 4>, 4>;

/// World to camera space as a row-vector matrix: the columns are right, up and forward.
Rows worldToCameraRows(const CameraDesc& camera, const CameraBasis& b) {
    const glm::dvec3 axes[3] = {b.right, b.up, b.forward};
    Rows m{};
    for (size_t c = 0; c < 3; ++c) {
        for (size_t r = 0; r < 3; ++r) m[r][c] = axes[c][int(r)];
        m[3][c] = -glm::dot(camera.eye, axes[c]);
    }
    m[3][3] = 1;
    return m;
}

ExrMatrix toFloat(const Rows& rows) {
    ExrMatrix m;
    for (size_t r = 0; r < 4; ++r)
        for (size_t c = 0; c < 4; ++c) m.m[r][c] = float(rows[r][c]);
    return m;
}

}  // namespace

ExrMatrix worldToCameraMatrix(const CameraDesc& camera) { return toFloat(worldToCameraRows(camera, cameraBasis(camera))); }

ExrMatrix worldToNdcMatrix(const CameraDesc& camera) {
    // Camera space (x, y, z) to NDC: x' = 0.5 + 0.5 x / (z tan aspect), y' = 0.5 - 0.5 y / (z tan),
    // as homogeneous (0.5 z + x / (2 tan aspect), 0.5 z - y / (2 tan), 1, z).
    const CameraBasis b = cameraBasis(camera);
    const double sx = 0.5 / (b.tanHalf * b.aspect), sy = 0.5 / b.tanHalf;
    const Rows p = {{{sx, 0, 0, 0}, {0, -sy, 0, 0}, {0.5, 0.5, 0, 1}, {0, 0, 1, 0}}};
    const Rows w2c = worldToCameraRows(camera, b);
    Rows m{};
    for (size_t r = 0; r < 4; ++r)
        for (size_t c = 0; c < 4; ++c)
            for (size_t k = 0; k < 4; ++k) m[r][c] += w2c[r][k] * p[k][c];
    return toFloat(m);
}

std::vector<ExrAttribute> cameraAttributes(const CameraDesc& camera) {
    return {{"worldToCamera", worldToCameraMatrix(camera)}, {"worldToNDC", worldToNdcMatrix(camera)}};
}

}  // namespace penumbra
