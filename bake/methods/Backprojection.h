#pragma once
/// @file Backprojection.h
/// @brief The default lookup of `--method penumbra-map`: the visible fraction of a receiver from
/// the light's shadow map by backprojection (in the manner of Guennebaud, Barthe & Paulin 2006),
/// which gives inner as well as outer penumbrae and combines overlapping blockers, where Wyman &
/// Hansen's penumbra map gives only the outer half and the darkest of overlapping penumbrae.
///
/// Seen from the light's centre, the point at depth z on the segment from a receiver r (depth
/// z_r, image position t_r) to a light point at lateral offset l lies at image position
/// t_r + k l, with k = 1/z - 1/z_r (perspective; t in tangent units, l in world units) or
/// k = z_r - z (orthographic, a sun; t in world units, l in tangent units). So a shadow-map texel
/// at depth z in front of r hides the light points l = (t - t_r) / k under its footprint. The
/// lookup marks those points on a grid of cells over the light's outline, one texel of a depth
/// pyramid at a time, and returns the share of the light left unmarked.
///
/// The shadow map keeps the nearest few surfaces per texel (DepthMap's layers), so blockers hidden
/// from the centre behind nearer ones (stacked grids) still count. Each layer's pyramid keeps, per
/// coarse texel, its nearest depth and four quantiles of its fine texels'
/// depths, so a coarse texel hides a quarter of the light points under it per quantile in front of
/// the receiver. The level is chosen per receiver so that the search region (the light's outline
/// scaled by k of the nearest blocker around) spans at most a few texels: the cost per receiver
/// is bounded and does not depend on the light's sample count.
///
/// Approximations: only the nearest few surfaces seen from the centre are known (blockers hidden
/// behind them from the centre are missed, so overlapped blockers let a little too much light
/// through);
/// overlapping blockers of partial coverage combine as independent (transmissions multiply); a
/// blocker nearer than a few texels to the receiver's own plane is not seen (the bias).

#include "bake/methods/LightView.h"
#include "stream/util/TexelIndex.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

/// @brief Coarse levels of a shadow map: per texel the nearest depth and four quantiles of the
/// depths of the fine texels under it (+infinity: nothing drawn).
class DepthPyramid {
public:
    static constexpr int kQuantiles = 4;
    struct Texel {
        float nearest;
        std::array<float, kQuantiles> quantile;  ///< ascending
    };

    /// @brief Builds levels 1, 2, ... down to one texel from layer @p layer of @p shadow (level 0,
    /// not copied).
    DepthPyramid(const DepthMap& shadow, int layer);

    int levels() const { return int(levels_.size()) + 1; }
    int resolution(int level) const { return level == 0 ? shadow_->res : res_[size_t(level - 1)]; }
    Texel at(int level, int x, int y) const;
    /// One level's texels, read without at()'s per-texel choice of level (the lookups' inner loop).
    /// The nearest depths and the quantiles are separate planes, so that the search, which reads
    /// only the nearest, reads 4 bytes per texel, not 20.
    struct Level {
        const float* nearest;                           ///< levels >= 1
        const std::array<float, kQuantiles>* quantile;  ///< levels >= 1
        const float* depth;                             ///< level 0: the layer of the shadow map
        int res;
        Texel at(int x, int y) const {
            if (nearest) return texel(x, y);
            const float z = depthAt(x, y);
            return {z, {z, z, z, z}};
        }
        Texel texel(int x, int y) const { return {nearest[size_t(y) * res + x], quantile[size_t(y) * res + x]}; }  ///< levels >= 1
        /// The nearest depth of every texel, row after row (level 0: the depths themselves).
        const float* nearestPlane() const { return nearest ? nearest : depth; }
        float nearestAt(int x, int y) const { return nearestPlane()[size_t(y) * res + x]; }
        float depthAt(int x, int y) const { return depth[size_t(y) * res + x]; }  ///< level 0
    };
    Level level(int l) const;
    /// The nearest depth of the whole map.
    float nearest() const;
    /// The texels [x0, x1] x [y0, y1] of @p level that cover the fine-texel box [@p lo, @p hi],
    /// clamped to the level.
    struct TexelRange {
        int x0, x1, y0, y1;
    };
    TexelRange texelsOver(int level, glm::dvec2 lo, glm::dvec2 hi) const {  // inline: three calls per lookup
        const int last = resolution(level) - 1;
        const double perTexel = std::ldexp(1.0, -level);  // x / 2^level exactly, without four divisions
        return {clampedTexel(std::floor(lo.x * perTexel), 0, last), clampedTexel(std::floor(hi.x * perTexel), 0, last),
                clampedTexel(std::floor(lo.y * perTexel), 0, last), clampedTexel(std::floor(hi.y * perTexel), 0, last)};
    }
    /// The nearest depth in the fine-texel box [lo, hi], read at @p level (whole texels).
    float nearestIn(int level, glm::dvec2 lo, glm::dvec2 hi) const;
    /// Bytes of the coarse levels (the `res²/3` texels of 20 bytes).
    static uint64_t plannedBytes(int resolution);

private:
    /// Texel (@p x, @p y) of level @p l from level l - 1, whose resolution is @p fine.
    Texel coarseTexel(int l, int fine, int x, int y) const;
    /// One coarse level's texels as two planes.
    struct Planes {
        std::vector<float> nearest;
        std::vector<std::array<float, kQuantiles>> quantile;
        void set(size_t i, const Texel& t) { nearest[i] = t.nearest, quantile[i] = t.quantile; }
    };
    /// Row @p y of level 1 into @p level from its texel @p first, four texels at a time where
    /// SSE4.1 is built in; returns how many texels it made (the rest are coarseTexel()'s). The
    /// same bits as coarseTexel().
    int firstLevelRow(int fine, int y, Planes& level, size_t first) const;

    const DepthMap* shadow_;
    int layer_;
    std::vector<int> res_;
    std::vector<Planes> levels_;
};

/// @brief The light's outline seen from its centre, as a grid of cells: the cells whose centres
/// lie inside the convex hull of the outline's points.
class LightGrid {
public:
    static constexpr int kCells = 12;  ///< cells per side (a row's cells are the bits of a uint16_t)

    /// @param outline the light bound's vertices in image axes (world units; a sun: tangents)
    explicit LightGrid(const std::vector<glm::dvec2>& outline);

    /// False for a light without area (a point): the hard test from the centre applies.
    bool hasArea() const { return !inside_.empty(); }
    glm::dvec2 lo, cell;              ///< the grid's corner and cell size
    glm::dvec2 hi() const { return lo + double(kCells) * cell; }  ///< the opposite corner
    double radius = 0;                ///< the largest distance of the outline from the centre
    /// A planar light seen obliquely: its depth along the view's axis per unit of image offset
    /// (0 for lights without a plane and suns). The plane test uses the light's real points:
    /// taken flat in the image plane, a receiver just in front of the light lost half of it.
    glm::dvec2 depthSlope{0.0};
    /// The cells inside the outline, as j * kCells + i.
    const std::vector<uint16_t>& insideCells() const { return inside_; }
    /// Per row j, bit i: the cell inside the outline (a lookup's starting state).
    const std::array<uint16_t, kCells>& openRows() const { return openRows_; }

private:
    std::vector<uint16_t> inside_;
    std::array<uint16_t, kCells> openRows_{};
};

/// @brief The visible fraction of receiver @p r (normal @p normal, may be zero) from @p view by
/// backprojection of the layers of its shadow map, read through @p pyramids (one per layer,
/// nearest first), onto @p grid.
/// @param bias the depth bias in texels (of the level read), as for the hard test
/// @param eps the rule's receiver epsilon at r, the smallest distance of a blocker from r's plane
/// @param taps texels read each side of the receiver, at the pyramid level where the search
/// region spans at most that many: (2 taps + 1)^2 texels per layer at most. More taps read a finer
/// level (sharper penumbrae, fewer quantile approximations) at a cost that grows as taps^2.
float backprojectedVisibility(const LightView& view, std::span<const DepthPyramid> pyramids, const LightGrid& grid,
                              const glm::dvec3& r, const glm::dvec3& normal, double bias, double eps, int taps);

}  // namespace penumbra
