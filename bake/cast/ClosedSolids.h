#pragma once
/// @file ClosedSolids.h
/// @brief Finds the closed solids that a light can reach inside, so that closed-caster culling
/// (Sintorn et al. 2008, bake.closed_casters) never loses a shadow silently.
///
/// Skipping a closed surface's triangle that faces away from the whole light is exact only when
/// no light sample lies inside that triangle's solid: the segment that enters the solid there
/// must leave it again through a face that blocks. The scan pass therefore follows the solids of
/// the stream (kTriangleSolidStart marks where one begins; a run of closed triangles without marks
/// is one solid) and keeps the box of the current one only. A solid whose box meets the box of a
/// point light's sample bound (a conservative test: a sample inside the solid is inside its box)
/// is *opened*: its triangles are cast as open surfaces (OpenSolidsSource clears their closed
/// mark in every later pass, which reads the stream in the same order). A sun's samples are at
/// infinity and are never inside a solid.
///
/// A solid that is not watertight (an edge without its reverse: a hole, a crack, a flipped face;
/// EdgeBalance.h) or is wound inward (OutwardVolume) is opened as well, whatever the lights: a
/// part of it wound inward counts: each run whose edges balance is checked as it streams, and a
/// solid of up to kMaxCheckedSolidTriangles has each of its edge-connected parts checked
/// (solidParts()), so parts whose triangles interleave are told apart too; a
/// wrong `"closed": true` mark would otherwise lose the shadows of the faces it skips. Such solids are counted per geometry entry,
/// so that the bake can name the entries whose mark was wrong.
///
/// A solid with both opaque faces and faces that may not block (cut-out, translucent or not
/// casting) is opened too: the face where a segment leaves it might let the segment through.
///
/// So is a solid whose triangles cross one another (SolidSelfIntersection.h: a watertight,
/// outward surface pushed through itself has regions of negative winding number), and one of
/// more than kMaxCheckedSolidTriangles triangles, which the scan cannot hold to check.
///
/// Memory: one box and two edge sums while scanning, the current solid's triangles up to
/// kMaxCheckedSolidTriangles (kSolidCheckBytes), plus the ordinals of the opened solids (8 bytes
/// each), which are only the solids that touch a light's box, are not watertight or cross themselves.

#include "bake/cast/EdgeBalance.h"
#include "bake/cast/SolidSelfIntersection.h"
#include "bake/light/Light.h"
#include "stream/TriangleSource.h"

#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

/// @brief Splits a stream into closed solids. Feed every triangle in stream order; the same
/// stream always gives the same solids and ordinals.
class SolidSegmenter {
public:
    static constexpr uint64_t kNone = ~uint64_t(0);
    /// @return the ordinal of the solid @p t belongs to, or kNone for an open triangle.
    uint64_t next(const Triangle& t) {
        if (!(t.flags & kTriangleClosed)) return inSolid_ = false, kNone;
        if (!inSolid_ || (t.flags & kTriangleSolidStart)) ++count_, inSolid_ = true;
        return count_ - 1;
    }
    uint64_t solids() const { return count_; }
    void reset() { count_ = 0, inSolid_ = false; }

private:
    uint64_t count_ = 0;
    bool inSolid_ = false;
};

/// @brief What the scan found: which solids are opened, and why.
struct OpenedSolids {
    std::vector<uint64_t> ordinals;       ///< sorted
    uint64_t triangles = 0;               ///< closed triangles that are cast as open
    std::vector<uint64_t> perLight;       ///< solids each light reaches inside
    /// Solids that are not watertight or wound inward, per geometry entry (the stream's part()):
    /// only entries that have one are listed, in stream order.
    struct Leaky {
        uint32_t part = 0;
        uint64_t solids = 0;     ///< of the entry's closed solids, those not watertight
        uint64_t inward = 0;     ///< those watertight but wound inward (or flat)
        uint64_t crossing = 0;   ///< those watertight and outward whose triangles cross one another
        uint64_t unchecked = 0;  ///< those watertight and outward too large to check for crossings
        uint64_t triangles = 0;  ///< the triangles of all four
    };
    std::vector<Leaky> leaky;
    uint64_t kept = 0;                    ///< closed solids that stay closed
    /// The smallest side of the box of any solid that stays closed (+infinity: none).
    float smallestExtent = INFINITY;
    /// Set by the bake when closedCastersSafe() turned closed casters off for this scale.
    bool castersOffForScale = false;
    uint64_t leakySolids() const {
        uint64_t n = 0;
        for (const Leaky& l : leaky) n += l.solids + l.inward;
        return n;
    }
    /// Solids opened because their triangles cross, and because they were too many to check.
    uint64_t crossingSolids() const {
        uint64_t n = 0;
        for (const Leaky& l : leaky) n += l.crossing;
        return n;
    }
    uint64_t uncheckedSolids() const {
        uint64_t n = 0;
        for (const Leaky& l : leaky) n += l.unchecked;
        return n;
    }
};

/// The largest share of the smallest closed solid that the rule's receiver epsilon may reach with
/// closed casters on (closedCastersSafe()).
inline constexpr double kClosedEpsilonShare = 1e-2;

/// @brief Whether skipping closed faces is safe at this scale. The argument behind closed casters
/// (a segment that leaves a solid through a skipped face entered it through a face that blocks
/// it) needs the receiver to lie more than eps(r) behind that entry face, and a receiver within
/// eps(r) of its plane is not blocked by it (BlockingRule.h). With eps(r) a tiny share of the
/// solids this takes a segment grazing the entry face within eps(r), and none was seen on the
/// examples or in random scenes near the origin; far from the origin eps(r) = epsilon |r| grows
/// to the size of the solids, and a sweep of such scenes lost blocked relations in 17 of 91. So
/// closed casters are turned off when @p epsilonMax (epsilon times L, the largest eps(r)) is more
/// than kClosedEpsilonShare of @p opened's smallest closed solid.
inline bool closedCastersSafe(const OpenedSolids& opened, double epsilonMax) {
    return !(epsilonMax > kClosedEpsilonShare * double(opened.smallestExtent));
}

/// @brief Scan-pass half: tracks the current solid's box, edge balance and volume, and opens the solids
/// whose box meets a point light's box (the light's sample bound, with a relative margin) and
/// those that are not watertight or wound inward.
class ClosedSolidScan {
public:
    explicit ClosedSolidScan(const LightSamples& samples);
    /// @param chunk the next triangles of the stream
    /// @param part the geometry entry they came from (TriangleSource::part()), for OpenedSolids::leaky
    void scan(std::span<const Triangle> chunk, uint32_t part = 0);
    /// @brief Ends the scan (closes the last solid) and returns the result.
    OpenedSolids finish();

private:
    struct Aabb {
        glm::vec3 lo, hi;
    };
    void closeSolid();

    std::vector<Aabb> lights_;  ///< per light; empty box for directional lights
    SolidSegmenter segmenter_;
    uint64_t current_ = SolidSegmenter::kNone, currentTriangles_ = 0;
    uint32_t currentPart_ = 0;  ///< the entry the current solid began in
    bool currentOpaque_ = false, currentSeeThrough_ = false;  ///< it has faces that block as opaque / may not
    bool currentRunInward_ = false;  ///< a balanced run of its triangles was not wound outward
    OutwardVolume runVolume_;        ///< the current run's, since the edges last balanced
    Aabb box_{};
    EdgeBalance edges_;
    OutwardVolume volume_;
    std::vector<SolidTriangle> triangles_;  ///< the current solid's, up to kMaxCheckedSolidTriangles
    bool tooMany_ = false;                  ///< the current solid has more
    OpenedSolids result_;
};

/// @brief Later passes' half: clears kTriangleClosed on the triangles of the opened solids.
class OpenSolidsSource final : public TriangleSource {
public:
    OpenSolidsSource(TriangleSourcePtr inner, std::vector<uint64_t> opened)
        : inner_(std::move(inner)), opened_(std::move(opened)) {}
    size_t read(std::span<Triangle> out) override;
    void rewind() override { inner_->rewind(), segmenter_.reset(), nextOpened_ = 0; }
    std::string name() const override { return inner_->name(); }
    std::optional<uint64_t> sizeHint() const override { return inner_->sizeHint(); }
    uint32_t part() const override { return inner_->part(); }
    std::vector<uint64_t> costRuns() const override { return inner_->costRuns(); }

private:
    TriangleSourcePtr inner_;
    std::vector<uint64_t> opened_;
    SolidSegmenter segmenter_;
    size_t nextOpened_ = 0;
};

}  // namespace penumbra
