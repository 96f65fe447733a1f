#include "bake/volume/VolumeKind.h"

#include "bake/volume/OpenVdb.h"
#include "bake/kinds/ReceiverKind.h"
#include "bake/Scene.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Prune.h>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace penumbra {
namespace {

/// Most voxels a volume bake has: receivers are indexed by 32 bits elsewhere.
constexpr uint64_t kMaxVolumeVoxels = uint64_t(1) << 30;
/// Most lattice points a narrow band's triangle boxes may hold together (each is a distance test).
constexpr double kMaxBandVisits = double(uint64_t(1) << 34);
/// Largest lattice index along an axis: OpenVDB's Coord is 32-bit and its trees add node offsets.
constexpr double kMaxLatticeIndex = double(1 << 30);

/// Voxel (i,j,k) has its centre, and its receiver, at origin + h * (i,j,k).
struct Lattice {
    double h = 0.1;
    glm::dvec3 origin{0.0};
    glm::dvec3 centre(const openvdb::Coord& c) const { return origin + h * glm::dvec3(c.x(), c.y(), c.z()); }
};

/// Closest point to @p p on triangle (a, b, c), by the Voronoi regions of its vertices and edges.
glm::dvec3 closestOnTriangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
    const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) return a;
    const glm::dvec3 bp = p - b;
    const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) return b;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
    const glm::dvec3 cp = p - c;
    const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) return c;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    const double denom = va + vb + vc;
    if (!(std::abs(denom) > 0)) return a;  // degenerate: the vertex and edge tests above decide
    return a + ab * (vb / denom) + ac * (vc / denom);
}

class VolumeKind final : public ReceiverKind {
public:
    /// @param band the geometry entries (indices into the scene's list) whose triangles the narrow
    /// band surrounds; empty for a box.
    VolumeKind(Lattice lattice, openvdb::CoordBBox box, std::vector<size_t> band, double width, bool irradiance, std::string where)
        : lattice_(lattice), box_(box), width_(width), irradiance_(irradiance), where_(std::move(where)) {
        for (size_t entry : band) {
            if (entry >= inBand_.size()) inBand_.resize(entry + 1, false);
            inBand_[entry] = true;
        }
    }

    std::optional<uint64_t> receiverBound() const override {
        if (!inBand_.empty()) return std::nullopt;  // only the band's triangles tell
        return uint64_t(box_.volume());
    }

    // The band is marked in the scan pass, from the chunks of its entries: the source is read
    // no more often for a volume than for any other kind.
    bool wantsPass(StreamPass pass) const override { return pass == StreamPass::Scan && !inBand_.empty(); }
    void consume(StreamPass pass, const StreamChunk& chunk) override {
        if (chunk.entry < inBand_.size() && inBand_[chunk.entry]) markBand(chunk.triangles);
    }

    ReceiverSet receivers() override {
        initializeOpenVdb();
        coords_.clear();
        if (inBand_.empty()) {
            for (int i = box_.min().x(); i <= box_.max().x(); ++i)
                for (int j = box_.min().y(); j <= box_.max().y(); ++j)
                    for (int k = box_.min().z(); k <= box_.max().z(); ++k) coords_.emplace_back(i, j, k);
        } else if (band_) {
            // Leaf by leaf, voxel by voxel: a deterministic order for the receivers.
            for (auto leaf = band_->tree().cbeginLeaf(); leaf; ++leaf)
                for (auto v = leaf->cbeginValueOn(); v; ++v) coords_.push_back(v.getCoord());
            band_.reset();
        }
        ReceiverSet set;
        set.position.reserve(coords_.size());
        for (const openvdb::Coord& c : coords_) set.position.push_back(glm::vec3(lattice_.centre(c)));
        set.normal.assign(coords_.size(), glm::vec3(0.f));  // zero: no receiver cosine
        return set;
    }

    void write(const OutputContext& c) override {
        initializeOpenVdb();
        auto transform = openvdb::math::Transform::createLinearTransform(lattice_.h);
        transform->postTranslate(openvdb::Vec3d(lattice_.origin.x, lattice_.origin.y, lattice_.origin.z));
        openvdb::CoordBBox bounds;
        for (const openvdb::Coord& coord : coords_) bounds.expand(coord);

        // docs/scene-format.md#volume: every baked voxel is active (lit ones too, so the grid's
        // bounds are the baked region in Blender and Houdini), the background 0 is "not baked".
        // Constant regions, lit or umbra, still prune to active tiles.
        openvdb::FloatGrid::Ptr visibility = openvdb::FloatGrid::create(0.0f);
        openvdb::Vec3SGrid::Ptr irradiance = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.f));
        {
            auto v = visibility->getAccessor();
            auto e = irradiance->getAccessor();
            for (size_t r = 0; r < coords_.size(); ++r) {
                v.setValue(coords_[r], c.results.visibility[r]);
                if (irradiance_) {
                    const glm::vec3& x = c.results.irradiance[r];
                    e.setValue(coords_[r], openvdb::Vec3s(x.x, x.y, x.z));
                }
            }
        }
        openvdb::GridPtrVec grids;
        auto finish = [&](openvdb::GridBase::Ptr grid, const char* name, openvdb::GridClass gridClass) {
            grid->setName(name);
            grid->setGridClass(gridClass);
            // The copy constructor shares the scale-and-translate map; Transform::copy() would
            // "simplify" it through an affine matrix, which recomputes the voxel size as
            // (origin + h) - origin: 0.0499...98 for 0.05, not the voxel_size given.
            grid->setTransform(std::make_shared<openvdb::math::Transform>(*transform));
            if (!coords_.empty()) {
                grid->insertMeta("penumbra_min", openvdb::Vec3IMetadata(bounds.min().asVec3i()));
                grid->insertMeta("penumbra_max", openvdb::Vec3IMetadata(bounds.max().asVec3i()));
            }
            grids.push_back(grid);
        };
        openvdb::tools::prune(visibility->tree(), 0.0f);  // tolerance 0: only exactly constant nodes
        // V in [0, 1] is a density a renderer shows as it is: lit air glows, umbra is empty.
        finish(visibility, "visibility", openvdb::GRID_FOG_VOLUME);
        if (irradiance_) {
            openvdb::tools::prune(irradiance->tree(), openvdb::Vec3s(0.f));
            // W/m^2 per channel is neither a density nor a distance: no class fits.
            finish(irradiance, "irradiance", openvdb::GRID_UNKNOWN);
        }

        ensureParentDirectory(c.output);
        AtomicFile out(c.output);
        writeVdbFile(out.tempPath(), c.output, grids);
        stampContentUuid(out.tempPath());  // the same grids, the same bytes
        out.commit();
    }

private:
    /// Marks every lattice point within width_ of a triangle of the band. The lattice points the
    /// triangles' boxes hold are counted as they come, and refused, with the numbers, before one
    /// more box would take more visits than a bake makes in reasonable time.
    void markBand(std::span<const Triangle> triangles) {
        if (!band_) initializeOpenVdb(), band_ = openvdb::MaskGrid::create(false);
        auto acc = band_->getAccessor();
        const double w2 = width_ * width_;
        for (const Triangle& t : triangles) {
            const glm::dvec3 a(t.v[0]), b(t.v[1]), cc(t.v[2]);
            const BoxLattice box = boxLattice(t);
            visits_ += box.count;
            if (visits_ > kMaxBandVisits)
                fail(where_, "the band's triangles cover more than {:.3g} lattice points at voxel_size {} and width {}, "
                             "more than a bake visits; raise voxel_size or lower width",
                     kMaxBandVisits, lattice_.h, width_);
            for (int i = box.lo.x; i <= box.hi.x; ++i)
                for (int j = box.lo.y; j <= box.hi.y; ++j)
                    for (int k = box.lo.z; k <= box.hi.z; ++k) {
                        const openvdb::Coord coord(i, j, k);
                        if (acc.isValueOn(coord)) continue;
                        const glm::dvec3 p = lattice_.centre(coord);
                        const glm::dvec3 d = p - closestOnTriangle(p, a, b, cc);
                        // Within the width up to the closest point's rounding: with width 0, the
                        // lattice points on a triangle (22 of 1089 on a floor were left out).
                        if (glm::dot(d, d) > w2 + box.slack * box.slack) continue;
                        acc.setValueOn(coord);
                        if (++marked_ > kMaxVolumeVoxels)
                            fail(where_, "the band holds more than {} voxels (receivers are indexed by 32 bits); raise "
                                         "voxel_size or lower width",
                                 kMaxVolumeVoxels);
                    }
        }
    }

    /// The lattice points of a triangle's box grown by the band width, and how many they are.
    struct BoxLattice {
        glm::ivec3 lo{0}, hi{-1};
        double count = 0;
        double slack = 0;  ///< markBand()'s rounding allowance for the box's points (kBandSlack of their size)
    };
    BoxLattice boxLattice(const Triangle& t) const {
        const glm::dvec3 a(t.v[0]), b(t.v[1]), c(t.v[2]);
        const glm::dvec3 low = glm::min(a, glm::min(b, c)), high = glm::max(a, glm::max(b, c));
        // Grown by markBand()'s slack, so that a lattice point on the box's face is visited; the
        // slack bounds the size of every point of the box, once per triangle.
        BoxLattice box;
        box.slack = kBandSlack * (glm::length(glm::max(glm::abs(low), glm::abs(high))) + width_ + 2 * lattice_.h);
        const glm::dvec3 lo = glm::ceil((low - width_ - box.slack - lattice_.origin) / lattice_.h);
        const glm::dvec3 hi = glm::floor((high + width_ + box.slack - lattice_.origin) / lattice_.h);
        for (int axis = 0; axis < 3; ++axis)
            // OpenVDB coordinates are 32-bit, with room for its node arithmetic.
            if (!(std::abs(lo[axis]) < kMaxLatticeIndex && std::abs(hi[axis]) < kMaxLatticeIndex))
                fail(where_, "a triangle of the band lies {:.3g} voxels from the origin, beyond the {:.3g} a lattice "
                             "index can reach; raise voxel_size",
                     std::max(std::abs(lo[axis]), std::abs(hi[axis])), kMaxLatticeIndex);
        if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) return box;
        box.lo = glm::ivec3(lo), box.hi = glm::ivec3(hi);
        box.count = (hi.x - lo.x + 1) * (hi.y - lo.y + 1) * (hi.z - lo.z + 1);
        return box;
    }

    /// A band's distances are compared up to this relative rounding (of the coordinates' size).
    static constexpr double kBandSlack = 1e-9;

    Lattice lattice_;
    openvdb::CoordBBox box_;
    std::vector<bool> inBand_;  ///< per geometry entry: in the narrow band (empty for a box)
    openvdb::MaskGrid::Ptr band_;  ///< the band's lattice points, during the scan pass
    double visits_ = 0;            ///< lattice points the band's triangle boxes held so far
    uint64_t marked_ = 0;
    double width_ = 0;
    bool irradiance_ = false;
    std::string where_;  ///< "scene.json: receivers.narrow_band", for messages
    std::vector<openvdb::Coord> coords_;
};

/// Parses [[x0,y0,z0],[x1,y1,z1]] with x0 <= x1 and so on.
void parseBox(const JsonParams& j, glm::dvec3& lo, glm::dvec3& hi) {
    const nlohmann::json* box = j.raw("box");
    auto corner = [&](size_t i, glm::dvec3& out) {
        const nlohmann::json& c = (*box)[i];
        if (!c.is_array() || c.size() != 3) return false;
        for (int a = 0; a < 3; ++a) {
            if (!c[size_t(a)].is_number()) return false;
            out[a] = c[size_t(a)].get<double>();
            if (!std::isfinite(out[a])) return false;
        }
        return true;
    };
    if (!box->is_array() || box->size() != 2 || !corner(0, lo) || !corner(1, hi))
        fail(j.where("box"), "expected [[x0,y0,z0],[x1,y1,z1]] (two corners of 3 finite numbers)");
    if (lo.x > hi.x || lo.y > hi.y || lo.z > hi.z) fail(j.where("box"), "the first corner must be the low one");
}

}  // namespace

namespace {

const ReceiverKindRegistration kVolume{"volume", [](const JsonParams& j, const SceneDesc& scene, KindUse use) -> std::unique_ptr<ReceiverKind> {
        Lattice lattice;
        lattice.h = j.number("voxel_size");
        if (!(lattice.h > 0) || !std::isfinite(lattice.h)) fail(j.where("voxel_size"), "must be a positive number");
        const bool irradiance = j.boolean("irradiance", false);
        requireOutputExtension(scene, {".vdb"}, "volume", /*oneFile=*/true);
        const bool hasBox = j.has("box"), hasBand = j.has("narrow_band");
        if (hasBox == hasBand) fail(j.where("box"), "give exactly one of \"box\" and \"narrow_band\"");
        constexpr double kMaxVoxels = double(kMaxVolumeVoxels);
        if (hasBox) {
            glm::dvec3 lo, hi;
            parseBox(j, lo, hi);
            glm::dvec3 n;
            for (int a = 0; a < 3; ++a) n[a] = std::max(1.0, std::ceil((hi[a] - lo[a]) / lattice.h - 1e-9));
            if (n.x * n.y * n.z > kMaxVoxels)
                fail(j.where("voxel_size"), "the box would have {:.3g} voxels (at most {:.0f})", n.x * n.y * n.z, kMaxVoxels);
            lattice.origin = lo + 0.5 * lattice.h;
            // Voxel centres are float receivers: the last one must be a finite float (a box at
            // 1e39, or a voxel of 1e300, was blamed on a receiver_offset the scene did not have).
            for (int a = 0; a < 3; ++a)
                if (const double last = lattice.origin[a] + (n[a] - 1) * lattice.h; !std::isfinite(float(lattice.origin[a])) ||
                                                                                   !std::isfinite(float(last)))
                    fail(j.where(std::max(std::abs(lo[a]), std::abs(hi[a])) > std::numeric_limits<float>::max() ? "box" : "voxel_size"),
                         "voxel centres would lie at {:.3g} along {}, beyond the float range of receiver positions (about 3.4e38)",
                         std::isfinite(float(lattice.origin[a])) ? last : lattice.origin[a], "xyz"[a]);
            openvdb::CoordBBox box(openvdb::Coord(0), openvdb::Coord(int(n.x) - 1, int(n.y) - 1, int(n.z) - 1));
            if (use == KindUse::Validate) return nullptr;
            return std::make_unique<VolumeKind>(lattice, box, std::vector<size_t>{}, 0.0, irradiance, j.where("box"));
        }
        JsonParams band(*j.raw("narrow_band"), j.file(), j.path("narrow_band"));
        const double width = band.number("width");
        if (!(width >= 0) || !std::isfinite(width)) fail(band.where("width"), "must be a non-negative number");
        // Around one triangle alone the band holds about (2 width / h)^3 voxels.
        if (const double around = std::pow(2 * width / lattice.h + 1, 3); around > kMaxVoxels)
            fail(band.where("width"), "a band {} wide holds about {:.3g} voxels of size {} around a single triangle, more "
                                      "than the {:.0f} a bake can hold",
                 width, around, lattice.h, kMaxVoxels);
        std::vector<size_t> entries = geometryIndices(band, "geometry", scene);
        band.finish();
        if (use == KindUse::Validate) return nullptr;
        return std::make_unique<VolumeKind>(lattice, openvdb::CoordBBox(), std::move(entries), width, irradiance, band.where());
    }, ".vdb"};

}  // namespace

}  // namespace penumbra
