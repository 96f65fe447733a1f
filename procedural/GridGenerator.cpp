#include "procedural/GridGenerator.h"

#include "procedural/BoxFaces.h"

#include "procedural/IndexedSource.h"
#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"

#include <glm/trigonometric.hpp>

#include <cmath>
#include <utility>

namespace penumbra {
namespace {

class GridSource final : public IndexedSource {
public:
    explicit GridSource(const GridParams& p)
        : IndexedSource("grid", count(p)), p_(p), elements_(uint64_t(p.cells + 1) * (p.cells + 1)),
          perElement_(p.thickness > 0 ? 12 : 2), floor_(p.floorSize > 0 ? 2 : 0) {}

    static uint64_t count(const GridParams& p) {
        return (p.floorSize > 0 ? 2 : 0) + uint64_t(p.levels) * (p.cells + 1) * (p.cells + 1) * (p.thickness > 0 ? 12 : 2);
    }

protected:
    void triangle(uint64_t index, Triangle& out) const override {
        out.flags = 0;
        if (index < floor_) {
            double h = 0.5 * p_.floorSize;
            glm::dvec3 c = p_.center;
            glm::dvec3 q[4] = {c + glm::dvec3(-h, 0, -h), c + glm::dvec3(h, 0, -h), c + glm::dvec3(h, 0, h),
                               c + glm::dvec3(-h, 0, h)};
            int a = index == 0 ? 1 : 2;
            out.v = {glm::vec3(q[0]), glm::vec3(q[a + 1]), glm::vec3(q[a])};  // faces +y
            return;
        }
        uint64_t j = index - floor_;
        const uint64_t perLevel = elements_ * perElement_;
        int level = int(j / perLevel);
        uint64_t e = (j % perLevel) / perElement_;
        int t = int(j % perElement_);

        const double s = p_.size, pitch = s / p_.cells, w = p_.bar * pitch, half = 0.5 * s;
        double x0, x1, z0, z1;
        const uint64_t bars = uint64_t(p_.cells) + 1;
        if (e < bars) {  // full-length bar along x
            x0 = -half - 0.5 * w, x1 = half + 0.5 * w;
            z0 = double(e) * pitch - half - 0.5 * w, z1 = z0 + w;
        } else {  // bar segment along z between two x bars
            uint64_t k = (e - bars) / p_.cells, m = (e - bars) % p_.cells;
            x0 = double(k) * pitch - half - 0.5 * w, x1 = x0 + w;
            z0 = double(m) * pitch - half + 0.5 * w, z1 = double(m + 1) * pitch - half - 0.5 * w;
        }
        const double y = p_.center.y + p_.height + level * p_.spacing;
        const double angle = glm::radians(p_.rotateStep * level), ca = std::cos(angle), sa = std::sin(angle);
        auto place = [&](double x, double yy, double z) {
            return glm::vec3(float(p_.center.x + ca * x - sa * z), float(yy), float(p_.center.z + sa * x + ca * z));
        };
        if (perElement_ == 2) {
            glm::vec3 q[4] = {place(x0, y, z0), place(x1, y, z0), place(x1, y, z1), place(x0, y, z1)};
            out.v = t == 0 ? std::array{q[0], q[2], q[1]} : std::array{q[0], q[3], q[2]};
            return;
        }
        const double y0 = y - 0.5 * p_.thickness, y1 = y + 0.5 * p_.thickness;
        out.flags = kTriangleClosed | (t == 0 ? kTriangleSolidStart : 0u);  // a bar is a box
        auto corner = [&](int c) { return place(c & 1 ? x1 : x0, c & 2 ? y1 : y0, c & 4 ? z1 : z0); };
        out.v = {corner(kBoxFaceTriangles[t][0]), corner(kBoxFaceTriangles[t][1]), corner(kBoxFaceTriangles[t][2])};
    }

private:
    GridParams p_;
    uint64_t elements_, perElement_, floor_;
};

}  // namespace

GridParams parseGridParams(const SourceRequest& request) {
    JsonParams j(request.params, request.file, request.path);
    GridParams p;
    p.center = j.vec3("center", p.center);
    p.size = j.number("size", p.size);
    p.cells = int(j.integer("cells", p.cells, 1, 4096));
    p.bar = j.number("bar", p.bar);
    p.thickness = j.number("thickness", p.thickness);
    p.levels = int(j.integer("levels", p.levels, 0, 1024));
    p.height = j.number("height", p.height);
    p.spacing = j.number("spacing", p.spacing);
    p.rotateStep = j.number("rotate_step_deg", p.rotateStep);
    p.floorSize = j.number("floor_size", p.floorSize);
    j.finish();
    // Coordinates stay where floats can hold them (the generators' common bound, 1e9).
    if (!(p.size > 0 && p.size <= 1e9)) fail(j.where("size"), "must be in (0, 1e9], got {}", p.size);
    for (int a = 0; a < 3; ++a)
        if (!(std::abs(p.center[a]) <= 1e9)) fail(j.where("center"), "must be within +-1e9, got {}", p.center[a]);
    // Multiplied by each level's index: a step beyond a turn means nothing and overflows.
    if (!(std::abs(p.rotateStep) <= 360)) fail(j.where("rotate_step_deg"), "must be within +-360, got {}", p.rotateStep);
    for (auto [key, value] : {std::pair{"height", p.height}, {"spacing", p.spacing}, {"thickness", p.thickness}})
        if (!(std::abs(value) <= 1e9)) fail(j.where(key), "must be within +-1e9, got {}", value);
    if (!(std::abs(p.height) + p.levels * std::abs(p.spacing) <= 1e9))
        fail(j.where("spacing"), "the top level would lie beyond 1e9 ({} levels of {})", p.levels, p.spacing);
    if (!(p.bar > 0 && p.bar < 1)) fail(j.where("bar"), "must be in (0, 1), got {}", p.bar);
    if (p.thickness < 0) fail(j.where("thickness"), "must not be negative, got {}", p.thickness);
    if (!(p.floorSize >= 0 && p.floorSize <= 1e9)) fail(j.where("floor_size"), "must be in 0..1e9, got {}", p.floorSize);
    return p;
}

TriangleSourcePtr makeGridSource(const GridParams& params) { return std::make_unique<GridSource>(params); }

}  // namespace penumbra
