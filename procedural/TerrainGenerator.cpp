#include "procedural/TerrainGenerator.h"

#include "procedural/IndexedSource.h"
#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

/// Coordinates beyond this would lose all detail in float vertices; nobody needs them.
constexpr double kMaxCoordinate = 1e9;
/// Float steps a terrain cell spans at least, where its coordinates are largest.
constexpr int kMinimumCellSteps = 8;

/// Linear interpolation over the grid triangle containing (x, z). @p vx and @p vz give vertex
/// coordinates and @p vh vertex heights; TerrainField passes table look-ups and terrainHeight()
/// computes them, and since the arithmetic is shared both give the same bits.
template <typename CoordinateX, typename CoordinateZ, typename VertexHeight>
double interpolate(const TerrainParams& p, double x, double z, CoordinateX&& vx, CoordinateZ&& vz, VertexHeight&& vh) {
    auto cellOf = [](double offset, double size, int cells) {
        return int64_t(std::floor(std::clamp(offset * (double(cells) / size), 0.0, double(cells - 1))));
    };
    const int64_t i = cellOf(x - p.area.x0, p.area.sizeX(), p.cellsX);
    const int64_t k = cellOf(z - p.area.z0, p.area.sizeZ(), p.cellsZ);
    const double xa = vx(i), xb = vx(i + 1), za = vz(k), zb = vz(k + 1);
    const double fx = (x - xa) / (xb - xa), fz = (z - za) / (zb - za);
    // Below the diagonal (fx >= fz) the point is in triangle (i,k) (i+1,k+1) (i+1,k), else in
    // (i,k) (i,k+1) (i+1,k+1). Which one is a coin flip for scattered points, so select instead
    // of branching: a mispredicted branch cost more than the whole interpolation.
    const double h00 = vh(i, k), h10 = vh(i + 1, k), h01 = vh(i, k + 1), h11 = vh(i + 1, k + 1);
    const bool lower = fx >= fz;
    const double a = lower ? fx : fz, b = lower ? fz : fx, side = lower ? h10 : h01;
    return h00 + a * (side - h00) + b * (h11 - side);
}

double gridCoordinate(double lo, double hi, int cells, int64_t i) {
    // The last line is exactly hi, so neighbouring terrains with a shared edge meet without gaps.
    double v = i >= cells ? hi : lo + (hi - lo) * double(i) / double(cells);
    return double(float(v));
}

class TerrainSource final : public ItemSource {
public:
    explicit TerrainSource(const TerrainParams& p)
        : ItemSource("terrain", uint64_t(p.cellsX) * uint64_t(p.cellsZ), 2), field_(p) {}
    uint64_t residentBytes() const override { return field_.bytes(); }
    size_t read(std::span<Triangle> out) override {
        field_.prepare();
        return ItemSource::read(out);
    }

protected:
    void item(uint64_t cell, Triangle* out) const override {
        const TerrainParams& p = field_.params();
        const int64_t i = int64_t(cell % uint64_t(p.cellsX)), k = int64_t(cell / uint64_t(p.cellsX));
        auto vertex = [&](int64_t a, int64_t b) {
            return glm::vec3(float(field_.vertexX(a)), field_.vertexHeight(a, b), float(field_.vertexZ(b)));
        };
        const glm::vec3 v00 = vertex(i, k), v10 = vertex(i + 1, k), v01 = vertex(i, k + 1), v11 = vertex(i + 1, k + 1);
        // Both triangles wind so that their normals point up (+y).
        out[0] = Triangle{{v00, v11, v10}, 0};
        out[1] = Triangle{{v00, v01, v11}, 0};
    }

private:
    TerrainField field_;
};

}  // namespace

Area parseArea(const JsonParams& j, const std::string& key, const Area& fallback) {
    const nlohmann::json* v = j.raw(key);
    if (!v) return fallback;
    auto isPair = [](const nlohmann::json& e) {
        return e.is_array() && e.size() == 2 && e[0].is_number() && e[1].is_number();
    };
    if (!v->is_array() || v->size() != 2 || !isPair((*v)[0]) || !isPair((*v)[1]))
        fail(j.where(key), "expected [[x0, z0], [x1, z1]], got {}", v->dump());
    Area a{(*v)[0][0].get<double>(), (*v)[0][1].get<double>(), (*v)[1][0].get<double>(), (*v)[1][1].get<double>()};
    for (double c : {a.x0, a.z0, a.x1, a.z1})
        if (!(std::abs(c) <= kMaxCoordinate)) fail(j.where(key), "coordinates must be finite and within +-1e9, got {}", v->dump());
    if (!(a.x1 > a.x0 && a.z1 > a.z0)) fail(j.where(key), "area is empty: need x0 < x1 and z0 < z1, got {}", v->dump());
    return a;
}

TerrainParams parseTerrainParams(const JsonParams& j) {
    TerrainParams p;
    p.area = parseArea(j, "area", p.area);
    if (const nlohmann::json* r = j.raw("resolution")) {
        if (r->is_array()) {
            glm::dvec2 v = j.vec2("resolution");
            auto cells = [&](double c) {
                if (!(c >= 1 && c <= 65536 && c == std::floor(c)))
                    fail(j.where("resolution"), "cell counts must be integers in 1..65536, got {}", r->dump());
                return int(c);
            };
            p.cellsX = cells(v.x), p.cellsZ = cells(v.y);
        } else {
            p.cellsX = p.cellsZ = int(j.integer("resolution", 1, 65536));
        }
    }
    p.amplitude = j.number("amplitude", p.amplitude);
    p.baseHeight = j.number("base_height", p.baseHeight);
    p.noise.octaves = int(j.integer("octaves", p.noise.octaves, 1, 16));
    p.noise.frequency = j.number("frequency", p.noise.frequency);
    p.noise.lacunarity = j.number("lacunarity", p.noise.lacunarity);
    p.noise.gain = j.number("gain", p.noise.gain);
    p.seed = j.seed("seed", p.seed);
    j.finish();
    if (!(p.amplitude >= 0 && p.amplitude <= kMaxCoordinate))
        fail(j.where("amplitude"), "must be in 0..1e9, got {}", p.amplitude);
    if (!(std::abs(p.baseHeight) <= kMaxCoordinate)) fail(j.where("base_height"), "must be within +-1e9, got {}", p.baseHeight);
    if (!(p.noise.frequency > 0 && p.noise.frequency <= 1e6))
        fail(j.where("frequency"), "must be in (0, 1e6], got {}", p.noise.frequency);
    if (!(p.noise.lacunarity >= 1 && p.noise.lacunarity <= 16))
        fail(j.where("lacunarity"), "must be in 1..16, got {}", p.noise.lacunarity);
    if (!(p.noise.gain > 0 && p.noise.gain <= 2)) fail(j.where("gain"), "must be in (0, 2], got {}", p.noise.gain);
    // Every cell must stay wider than a few float steps there, or neighbouring vertices would
    // round together (kMinimumCellSteps; a 10 m elevation grid in UTM coordinates passes).
    const double reach = std::max({std::abs(p.area.x0), std::abs(p.area.x1), std::abs(p.area.z0), std::abs(p.area.z1), 1.0});
    const double step = double(std::nextafter(float(reach), INFINITY)) - double(float(reach));
    const double cell = std::min(p.area.sizeX() / p.cellsX, p.area.sizeZ() / p.cellsZ);
    if (cell < kMinimumCellSteps * step)
        fail(j.where("resolution"),
             "cells of {:g} are too small {:g} from the origin, where float coordinates are {:g} apart: a cell needs at least {} "
             "of those steps ({:g}); lower the resolution or move the area nearer the origin",
             cell, reach, step, kMinimumCellSteps, kMinimumCellSteps * step);
    return p;
}

TerrainParams parseTerrainParams(const SourceRequest& request) {
    return parseTerrainParams(JsonParams(request.params, request.file, request.path));
}

double terrainVertexX(const TerrainParams& p, int64_t i) { return gridCoordinate(p.area.x0, p.area.x1, p.cellsX, i); }
double terrainVertexZ(const TerrainParams& p, int64_t k) { return gridCoordinate(p.area.z0, p.area.z1, p.cellsZ, k); }

namespace {
float vertexHeightFrom(const TerrainParams& p, const Fbm& noise, int64_t i, int64_t k) {
    return float(p.baseHeight + p.amplitude * noise(terrainVertexX(p, i), terrainVertexZ(p, k)));
}
}  // namespace

float terrainVertexHeight(const TerrainParams& p, int64_t i, int64_t k) {
    return vertexHeightFrom(p, Fbm(p.seed, p.noise), i, k);
}

double terrainHeight(const TerrainParams& p, double x, double z) {
    const Fbm noise(p.seed, p.noise);
    return interpolate(
        p, x, z, [&](int64_t i) { return terrainVertexX(p, i); }, [&](int64_t k) { return terrainVertexZ(p, k); },
        [&](int64_t i, int64_t k) { return double(vertexHeightFrom(p, noise, i, k)); });
}

TerrainField::TerrainField(const TerrainParams& params) : p_(params), noise_(params.seed, params.noise) {
    const uint64_t columns = uint64_t(p_.cellsX) + 1, rows = uint64_t(p_.cellsZ) + 1;
    for (uint64_t i = 0; i < columns; ++i) xs_.push_back(terrainVertexX(p_, int64_t(i)));
    for (uint64_t k = 0; k < rows; ++k) zs_.push_back(terrainVertexZ(p_, int64_t(k)));
}

void TerrainField::prepare() const {
    if (!cached() || !heights_.empty()) return;
    const uint64_t columns = xs_.size(), rows = zs_.size();
    heights_.resize(columns * rows);
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, rows), [&](const tbb::blocked_range<uint64_t>& r) {
        for (uint64_t k = r.begin(); k != r.end(); ++k)
            for (uint64_t i = 0; i < columns; ++i) heights_[k * columns + i] = vertexHeightFrom(p_, noise_, int64_t(i), int64_t(k));
    });
}

float TerrainField::vertexHeight(int64_t i, int64_t k) const {
    if (heights_.empty()) return vertexHeightFrom(p_, noise_, i, k);
    return heights_[uint64_t(k) * (uint64_t(p_.cellsX) + 1) + uint64_t(i)];
}

double TerrainField::height(double x, double z) const {
    return interpolate(
        p_, x, z, [&](int64_t i) { return xs_[size_t(i)]; }, [&](int64_t k) { return zs_[size_t(k)]; },
        [&](int64_t i, int64_t k) { return double(vertexHeight(i, k)); });
}

TriangleSourcePtr makeTerrainSource(const TerrainParams& params) { return std::make_unique<TerrainSource>(params); }

}  // namespace penumbra
