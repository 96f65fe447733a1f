#pragma once
/// @file SampleMaskTable.h
/// @brief Sintorn, Eisemann & Assarsson 2008 (Section 4.2) plane-to-bitmask look-up table for one
/// planar light, made exact: it only decides relations that BlockingRule.h would decide the same
/// way despite roundoff, and leaves every other relation to the exact per-sample test.
///
/// For a receiver r and a blocker T with the light entirely on one side of T's plane, sample l
/// (homogeneous weight w) is blocked when, for each edge (a, b) of T, the edge plane through a, b
/// and l has r on its non-negative side. In real arithmetic that edge value is
/// sigma * det(l - w a, b - a, r - a) = sigma * m . (l - w a) with m = (b - a) x (r - a) and sigma
/// the (per light constant) side of the samples: an affine function of l. Restricted to the
/// light's plane (for a sun, the plane of its directions) it is a half-plane, "the inner side of a
/// line". The table is indexed by the
/// line's direction (as a diamond angle, see SampleMaskTable.cpp) and signed offset in a 2D frame
/// of the light plane, and each cell holds, per group
/// of samples (one 64-bit word, same layout as LightSampleGroup), two masks:
///  - sure:  samples on the inner side of every line of the cell,
///  - maybe: samples on the inner side of some line of the cell.
/// A receiver ANDs the three edges' words: blocked contains sure and is contained in maybe.
///
/// Exactness: the receiver's line is looked up with a margin delta (sure at offset + delta, maybe at
/// offset - delta) that bounds every difference between the rule's double evaluation and the
/// real-arithmetic half-plane: the 3D cross/dot roundoff, the roundoff of m, the samples' distance
/// from the fitted plane (they are float32 points), the frame, the angle binning and the table's own
/// rounding. The bound is derived in SampleMaskTable.cpp (lookup()) with generous constants; a
/// margin only moves bits from "decided" to "tested exactly", so over-estimating costs speed, never
/// correctness. Lines whose margin is not small against the light (planes nearly parallel to the
/// light, receivers or blockers far away relative to their size) fall back to the exact tests.

#include "bake/cast/HardShadowBlock.h"
#include "bake/rule/BlockingRule.h"
#include "bake/light/Light.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace penumbra {

/// @brief The look-up table of one light (all its sample sets); read-only once built, so shared
/// by all tiles and threads.
class SampleMaskTable {
public:
    /// @brief Builds the table for light @p light of @p samples.
    /// @param angles number of line-angle bins (of the diamond angle, a cheap monotone stand-in for
    /// the polar angle; at least 4)
    /// @param offsets number of signed-offset bins over [-R, R], R the light's radius in its plane;
    /// two more bins hold the offsets beyond either end
    /// The table is not usable() (every relation goes to the exact test) when the light's samples
    /// do not lie in a plane (sphere lights) or span no area, or when it would exceed 64 MiB.
    /// @param simd Avx2 or Auto (when the CPU has AVX2) looks up a receiver's three edge lines in
    /// one AVX2 pass; any other level one line at a time. The rows found are the same either way.
    SampleMaskTable(const LightSamples& samples, uint32_t light, int angles = 128, int offsets = 128,
                    SimdLevel simd = SimdLevel::Auto);

    /// @brief Bytes the table of light @p light would take (0 when over the 64 MiB cap, as then
    /// none is built), for memory planning. Sphere lights are counted though they get no table.
    static size_t plannedBytes(const LightSamples& samples, uint32_t light, int angles, int offsets);

    bool usable() const { return usable_; }
    /// @brief Bytes held by the mask arrays (cells and footprint bins).
    size_t bytes() const { return (cells_.size() + footprintRows_.size()) * sizeof(uint64_t); }

    /// @brief The rows of a split blocker's plane line per sample set and orientation: they do
    /// not depend on the receiver, so a caller that looks up many receivers against one blocker
    /// keeps them here (reset() before each blocker).
    struct SideCache {
        std::vector<const uint64_t*> rows;  ///< [set][orientation][sure, maybe]
        std::vector<uint8_t> state;         ///< [set][orientation]: 0 unknown, 1 rows, 2 exact
        void reset(int sets) { rows.resize(size_t(sets) * 4), state.assign(size_t(sets) * 2, 0); }
    };

    /// @brief What a blocker contributes, independent of the receiver.
    struct Blocker {
        SideCache* sideCache = nullptr;  ///< optional, for split blockers (see SideCache)
        bool usable = false;  ///< false: the table cannot help with this blocker (fall back)
        /// T's plane cuts the samples' box: per receiver, only the samples on the far side of T
        /// from it can be blocked, and they share one orientation; a fourth line (T's plane in
        /// the light's plane) selects them.
        bool split = false;
        double side = 0;      ///< HardShadowVolume::side of every sample of the light (not split)
        double sigma = 0;     ///< orientation of every edge plane (not split: -side; split: +1)
        double maxAbs = 0;    ///< largest |coordinate| of T and of the light's samples
        glm::dvec3 plane{0.0};  ///< split: T's plane in the light's frame, (n.u, n.v, n.(o - w v0))
        double planeNormal = 0;  ///< split: n . (the light plane's normal), for the flatness term
        /// Per edge (a, b): with m(r) = (b - a) x (r - a), the line's coefficients for
        /// orientation +1, wx = m.u, wy = m.v, k = m.(o - w a) and mn = m.n (frame u, v, n,
        /// origin o), are affine in r; each is stored as c0 - dot(c, r), [wx, wy, k, mn].
        /// Structure of arrays, [coefficient][edge], so that one AVX2 pass evaluates the three
        /// edges' lines at once; lane 3 repeats edge 2 (same result, never read).
        struct Lines {
            alignas(32) double c0[4][4];
            alignas(32) double cx[4][4];
            alignas(32) double cy[4][4];
            alignas(32) double cz[4][4];
            /// Coefficient @p j of edge @p e at @p r: c0 - dot(c, r), in glm::dot's order.
            double at(int j, int e, const glm::dvec3& r) const {
                return c0[j][e] - ((cx[j][e] * r.x + cy[j][e] * r.y) + cz[j][e] * r.z);
            }
            void set(int j, int e, double constant, const glm::dvec3& c) {
                c0[j][e] = constant, cx[j][e] = c.x, cy[j][e] = c.y, cz[j][e] = c.z;
            }
            /// Lane 3 := edge 2, once the three edges are set.
            void repeatLastEdge() {
                for (int j = 0; j < 4; ++j) c0[j][3] = c0[j][2], cx[j][3] = cx[j][2], cy[j][3] = cy[j][2], cz[j][3] = cz[j][2];
            }
        };
        Lines line;
    };
    /// @brief Classifies the light against @p t's plane (8 corners of the samples' box).
    Blocker prepare(const BlockerTriangle& t) const;

    /// @brief The three edges' cells for one receiver, and a fourth line selecting the samples on
    /// the far side of T (all samples unless the blocker is split). Each cell holds a sure and a
    /// maybe word per group, interleaved, so a cell of up to four groups is one cache line.
    struct Rows {
        const uint64_t* sure[4];
        const uint64_t* maybe[4];
        /// Sure-blocked samples of group @p k (index within the light's groups).
        uint64_t sureWord(uint32_t k) const {
            return sure[0][2 * k] & sure[1][2 * k] & sure[2][2 * k] & sure[3][2 * k];
        }
        /// Samples that may be blocked: every other sample of the group is certainly not blocked.
        uint64_t maybeWord(uint32_t k) const {
            return maybe[0][2 * k] & maybe[1][2 * k] & maybe[2][2 * k] & maybe[3][2 * k];
        }
        /// One edge's words (tests check each line on its own).
        uint64_t sureWord(int edge, uint32_t k) const { return sure[edge][2 * k]; }
        uint64_t maybeWord(int edge, uint32_t k) const { return maybe[edge][2 * k]; }
    };
    enum class Lookup {
        Exact,        ///< the table cannot decide here: test every open sample exactly
        NoneBlocked,  ///< the receiver is not behind T beyond eps from the light: nothing blocked
        Rows,         ///< use Rows::sureWord / maybeWord
    };
    /// @brief Looks up receiver @p r (sample set @p set) against blocker @p b.
    /// @param dist distanceBehind(T, r), as the caller computed it for the exact rule
    /// @param eps the receiver's epsilon (receiverEpsilon())
    /// @param rows filled when the result is Lookup::Rows
    Lookup lookup(const Blocker& b, uint32_t set, const glm::dvec3& r, double dist, double eps, Rows& rows) const;

    /// @brief A split blocker's footprint on the light, seen from one receiver: a box of the
    /// light's plane (in its frame, as bins of the samples' coordinates) that holds every sample
    /// the rule could find blocked (SampleMaskTableFootprint.cpp derives it from lookup()'s error
    /// budget). A thin face seen from beside reaches many receivers of a large light but covers
    /// few samples of any; the box ends most such pairs before V_Gk and the exact tests
    /// (docs/performance.md, "Footprints of split blockers").
    struct Footprint {
        /// Per group of the light: samples of the set outside the box in s or t are cleared.
        const uint64_t* sLow;
        const uint64_t* sHigh;
        const uint64_t* tLow;
        const uint64_t* tHigh;
        /// The samples of group @p k (index within the light's groups) that may be blocked.
        uint64_t word(uint32_t k) const { return sLow[k] & sHigh[k] & tLow[k] & tHigh[k]; }
    };
    enum class FootprintResult {
        Unknown,      ///< no usable bound here (every sample stays a candidate)
        NoneBlocked,  ///< the receiver is within eps of T's plane: the rule blocks no sample
        Box,          ///< Footprint::word() bounds the blocked samples of each group
    };
    /// @brief The footprint of split blocker @p b from receiver @p r (sample set @p set): footprints()
    /// for one receiver.
    /// @param dist distanceBehind(T, r); @param eps the receiver's epsilon
    FootprintResult footprint(const Blocker& b, uint32_t set, const glm::dvec3& r, double dist, double eps,
                              Footprint& out) const {
        FootprintResult result;
        footprints(b, &r, &set, &dist, &eps, 1u, &result, &out);
        return result;
    }

    /// @brief footprint() for the receivers @p live (bits 0..3) of r[0..3], with their sample sets,
    /// distances behind T and epsilons; with AVX2, one receiver per lane (the chunks of a leaf).
    void footprints(const Blocker& b, const glm::dvec3* r, const uint32_t* set, const double* dist, const double* eps,
                    uint32_t live, FootprintResult* result, Footprint* out) const;

    /// @brief Index of the light's first group in LightSamples::groups (subtract it from a group).
    uint32_t firstGroup() const { return firstGroup_; }

private:
    static constexpr double kRoundoff = 0x1p-53;  ///< u: unit roundoff of double
    static double maxAbs(const glm::dvec3& p) { return std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}); }
    /// Bytes of the cells alone (0 over the cap, when no table is built).
    static size_t cellBytes(const LightSamples& samples, uint32_t light, int angles, int offsets);

    size_t cell(uint32_t set, int angle, int bin) const {
        return ((size_t(set) * angles_ + angle) * size_t(offsets_ + 2) + bin) * groups_ * 2;
    }
    /// Bounds of offset bin @p bin: [lower, upper); bin 0 and bin offsets_ + 1 are unbounded.
    double lower(int bin) const;
    double upper(int bin) const;
    /// The bin holding @p offset, consistent with lower() and upper() whatever the rounding.
    int offsetBin(double offset) const;
    /// The sure and maybe rows of the half-plane wx s + wy t + k >= 0 in sample set @p set, with
    /// @p fixed the error bound that does not scale with the line and @p mn its flatness factor.
    /// @return false when the line is too uncertain for the table to decide anything.
    bool sideRows(const Blocker& b, uint32_t set, double s, double m, const uint64_t*& sure, const uint64_t*& maybe) const;
    bool lineRows(double wx, double wy, double k, double mn, double fixed, double m, uint32_t set, const uint64_t*& sure,
                  const uint64_t*& maybe) const;
    /// The part of a line's margin that scales with the line (lookup()'s error budget): divided
    /// by g it is lineRows()'s delta but for the offset's own rounding; footprints use it times g.
    double lineMargin(double norm1, double fixed, double m) const {
        return 2.0 * (fixed + norm1 * (flatness_ + 128 * kRoundoff * m));
    }
    /// The three edges' rows of @p b at @p r with orientation @p s, in one AVX2 pass: the same
    /// operations as three lineRows() calls, lane by lane (SampleMaskTableAvx2.cpp).
    bool edgeRowsAvx2(const Blocker& b, uint32_t set, const glm::dvec3& r, double s, double fixed, double m, Rows& rows) const;

    bool usable_ = false;
    bool avx2_ = false;  ///< edgeRowsAvx2() looks up the edges' lines
    int angles_, offsets_;
    uint32_t firstGroup_ = 0, groups_ = 0;
    glm::dvec3 origin_{0.0}, u_{0.0}, v_{0.0}, n_{0.0};  ///< frame of the light plane
    double radius_ = 0;     ///< R: every sample lies within R of origin_ in the plane (with slack)
    double width_ = 0, invWidth_ = 0;  ///< of an offset bin: 2R / offsets_, and its inverse
    double flatness_ = 0;   ///< H: bound on every sample's distance from the plane
    double maxAbs_ = 0;     ///< largest |coordinate| of any sample
    double w_ = 1.0;        ///< homogeneous weight of the light's samples (0: a sun's directions)
    glm::dvec3 lo_{0.0}, hi_{0.0};  ///< box of every sample (exact float values)
    std::vector<uint64_t> cells_;  ///< [set][angle][offset bin][group of the light][sure, maybe]
    std::vector<uint64_t> ones_;   ///< a row of all-ones words: the fourth line of a blocker that is not split

    // Footprints (SampleMaskTableFootprint.cpp): the samples' coordinates in kFootprintBins bins
    // per axis, and per [set][axis][side][bin] a row of one word per group of the light: side 0
    // holds the samples in this bin or above it, side 1 those in this bin or below it.
    static constexpr int kFootprintBins = 32;
    void buildFootprintBins(const std::vector<glm::dvec2>& coords, const std::vector<uint32_t>& groupOf,
                            const std::vector<uint32_t>& bitOf, int sets);
    int footprintBin(int axis, double value) const;
    /// Lines within this (relative) of parallel give footprint vertices too uncertain to bound.
    static constexpr double kMinimumFootprintSine = 1e-4;
    /// The footprint's box in the light's frame for orientation @p s and coordinate bound @p m, as
    /// bins: s low, s high, t low, t high; false when the bound does not apply (footprint()).
    bool footprintBins(const Blocker& b, const glm::dvec3& r, double s, double m, int bins[4]) const;
    /// footprintBins() for four receivers (one per lane): bins[end][lane]; returns the lanes
    /// whose bound applies.
    uint32_t footprintBins4Avx2(const Blocker& b, const glm::dvec3* r, const double* s, const double* m, int bins[4][4]) const;
    size_t footprintIndex(uint32_t set, int axis, int side, int bin) const {
        return (((size_t(set) * 2 + axis) * 2 + side) * kFootprintBins + bin) * groups_;
    }
    const uint64_t* footprintRow(uint32_t set, int axis, int side, int bin) const {
        return &footprintRows_[footprintIndex(set, axis, side, bin)];
    }
    double binLow_[2] = {0, 0}, binScale_[2] = {0, 0};  ///< bin = floor((value - binLow_) * binScale_)
    std::vector<uint64_t> footprintRows_;
};

}  // namespace penumbra
