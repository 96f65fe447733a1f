#include "procedural/BoxesGenerator.h"

#include "procedural/BoxFaces.h"

#include "procedural/IndexedSource.h"
#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"

#include <glm/common.hpp>

#include <cmath>

namespace penumbra {
namespace {

class BoxSource final : public ItemSource {
public:
    BoxSource(std::vector<BoxShape> boxes, const std::string& name)
        : ItemSource(name, boxes.size(), 12), boxes_(std::move(boxes)) {}

protected:
    void item(uint64_t index, Triangle* out) const override {
        const BoxShape& b = boxes_[index];
        glm::vec3 corner[8];
        for (int c = 0; c < 8; ++c)
            corner[c] = glm::vec3(float(c & 1 ? b.hi.x : b.lo.x), float(c & 2 ? b.hi.y : b.lo.y), float(c & 4 ? b.hi.z : b.lo.z));
        for (int t = 0; t < 12; ++t)
            out[t] = Triangle{{corner[kBoxFaceTriangles[t][0]], corner[kBoxFaceTriangles[t][1]], corner[kBoxFaceTriangles[t][2]]},
                              kTriangleClosed | (t == 0 ? kTriangleSolidStart : 0u)};
    }

private:
    std::vector<BoxShape> boxes_;
};

BoxShape box(double x0, double y0, double z0, double x1, double y1, double z1) { return {{x0, y0, z0}, {x1, y1, z1}}; }

}  // namespace

std::vector<BoxShape> colonnadeBoxes(const ColonnadeParams& p) {
    std::vector<BoxShape> boxes;
    const double hx = 0.5 * p.courtyard.x, hz = 0.5 * p.courtyard.y, cw = 0.5 * p.columnWidth;
    const double ox = hx + p.gallery, oz = hz + p.gallery;  // inner face of the outer wall
    const glm::dvec3 c = p.center;
    auto add = [&](double x0, double y0, double z0, double x1, double y1, double z1) {
        boxes.push_back(box(c.x + x0, c.y + y0, c.z + z0, c.x + x1, c.y + y1, c.z + z1));
    };
    for (int s = 0; s < p.storeys; ++s) {
        const double y0 = s * p.storeyHeight, y1 = y0 + p.storeyHeight - p.slab, y2 = y0 + p.storeyHeight;
        auto column = [&](double x, double z) { add(x - cw, y0, z - cw, x + cw, y1, z + cw); };
        // Columns stand on the courtyard's edge; corner columns belong to the x sides.
        for (int i = 0; i < p.columns.x; ++i) {
            const double x = -hx + 2 * hx * i / (p.columns.x - 1);
            column(x, -hz), column(x, hz);
        }
        for (int k = 1; k + 1 < p.columns.y; ++k) {
            const double z = -hz + 2 * hz * k / (p.columns.y - 1);
            column(-hx, z), column(hx, z);
        }
        // The gallery ceiling: a ring of four slabs from the column line to the wall.
        add(-ox, y1, -oz, ox, y2, -hz + cw);
        add(-ox, y1, hz - cw, ox, y2, oz);
        add(-ox, y1, -hz + cw, -hx + cw, y2, hz - cw);
        add(hx - cw, y1, -hz + cw, ox, y2, hz - cw);
    }
    if (p.wall > 0) {
        const double top = p.storeys * p.storeyHeight, w = p.wall;
        add(-ox - w, 0, -oz - w, ox + w, top, -oz);
        add(-ox - w, 0, oz, ox + w, top, oz + w);
        add(-ox - w, 0, -oz, -ox, top, oz);
        add(ox, 0, -oz, ox + w, top, oz);
    }
    if (p.floor) add(-ox - p.wall, -0.1, -oz - p.wall, ox + p.wall, 0, oz + p.wall);
    return boxes;
}

std::vector<BoxShape> parseBoxes(const SourceRequest& request) {
    JsonParams j(request.params, request.file, request.path);
    const nlohmann::json* list = j.raw("boxes");
    j.finish();
    if (!list) j.missing("boxes");
    if (!list->is_array()) fail(j.where("boxes"), "expected an array of [[x0, y0, z0], [x1, y1, z1]] boxes");
    std::vector<BoxShape> boxes;
    for (size_t i = 0; i < list->size(); ++i) {
        nlohmann::json wrapper = {{"lo", (*list)[i].is_array() && (*list)[i].size() == 2 ? (*list)[i][0] : nlohmann::json()},
                                  {"hi", (*list)[i].is_array() && (*list)[i].size() == 2 ? (*list)[i][1] : nlohmann::json()}};
        const std::string key = "boxes[" + std::to_string(i) + "]";
        if (wrapper["lo"].is_null()) fail(j.where(key), "expected [[x0, y0, z0], [x1, y1, z1]], got {}", (*list)[i].dump());
        JsonParams b(wrapper, j.file(), j.path(key));
        BoxShape bx{b.vec3("lo"), b.vec3("hi")};
        if (!(bx.lo.x < bx.hi.x && bx.lo.y < bx.hi.y && bx.lo.z < bx.hi.z))
            fail(j.where(key), "box is empty: need x0 < x1, y0 < y1 and z0 < z1");
        for (int a = 0; a < 3; ++a)
            if (!(std::abs(bx.lo[a]) <= 1e9 && std::abs(bx.hi[a]) <= 1e9)) fail(j.where(key), "coordinates must be within +-1e9");
        boxes.push_back(bx);
    }
    return boxes;
}

ColonnadeParams parseColonnadeParams(const SourceRequest& request) {
    JsonParams j(request.params, request.file, request.path);
    ColonnadeParams p;
    p.center = j.vec3("center", p.center);
    for (int a = 0; a < 3; ++a)  // the generators' common bound, where floats still hold the parts
        if (!(std::abs(p.center[a]) <= 1e9)) fail(j.where("center"), "must be within +-1e9, got {}", p.center[a]);
    p.courtyard = j.vec2("courtyard", p.courtyard);
    p.gallery = j.number("gallery", p.gallery);
    if (const nlohmann::json* c = j.raw("columns")) {
        glm::dvec2 n = j.vec2("columns");
        if (!(n.x >= 2 && n.y >= 2 && n.x <= 1000 && n.y <= 1000 && n == glm::floor(n)))
            fail(j.where("columns"), "expected two integers in 2..1000, got {}", c->dump());
        p.columns = glm::ivec2(n);
    }
    p.columnWidth = j.number("column_width", p.columnWidth);
    p.storeyHeight = j.number("storey_height", p.storeyHeight);
    p.storeys = int(j.integer("storeys", p.storeys, 1, 100));
    p.slab = j.number("slab", p.slab);
    p.wall = j.number("wall", p.wall);
    p.floor = j.boolean("floor", p.floor);
    j.finish();
    if (!(p.courtyard.x > 0 && p.courtyard.y > 0 && p.courtyard.x <= 1e6 && p.courtyard.y <= 1e6))
        fail(j.where("courtyard"), "both sides must be in (0, 1e6], got [{}, {}]", p.courtyard.x, p.courtyard.y);
    if (!(p.columnWidth > 0 && p.columnWidth < std::min(p.courtyard.x / (p.columns.x - 1), p.courtyard.y / (p.columns.y - 1))))
        fail(j.where("column_width"), "must be positive and less than the column spacing, got {}", p.columnWidth);
    if (!(p.gallery > 0.5 * p.columnWidth && p.gallery <= 1e6))
        fail(j.where("gallery"), "must exceed half the column width and be at most 1e6, got {}", p.gallery);
    if (!(p.storeyHeight > 0 && p.storeyHeight <= 1e6)) fail(j.where("storey_height"), "must be in (0, 1e6], got {}", p.storeyHeight);
    if (!(p.slab > 0 && p.slab < p.storeyHeight)) fail(j.where("slab"), "must be positive and less than storey_height, got {}", p.slab);
    if (!(p.wall >= 0 && p.wall <= 1e6)) fail(j.where("wall"), "must be in 0..1e6, got {}", p.wall);
    return p;
}

TriangleSourcePtr makeBoxSource(std::vector<BoxShape> boxes, const std::string& name) {
    return std::make_unique<BoxSource>(std::move(boxes), name);
}

}  // namespace penumbra
