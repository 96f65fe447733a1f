#pragma once
/// @file LightView.h
/// @brief The light's-eye views of `--method penumbra-map` (Wyman & Hansen 2003): a perspective
/// view from the centre of an area light (or six cube faces when the receivers surround it), or an
/// orthographic view along a sun's central direction, each with a square map of depths, and the
/// scan conversion of triangles into them.
///
/// A view maps a world point to texel coordinates (x, y) in [0, res)^2 and a depth z: the
/// distance along the view axis (from the light's centre; for a sun, from an origin plane). The
/// texel grid is uniform in tangent space (perspective) or world units (orthographic), so an
/// image distance of d texels is an angle (tangent) of d * texel() or a lateral distance of
/// d * texel() world units.

#include "bake/light/Light.h"
#include "receivers/ReceiverSet.h"
#include "stream/AlphaTable.h"
#include "stream/Triangle.h"

#include <glm/vec2.hpp>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

/// @brief A projected point: texel coordinates and depth.
struct ViewPoint {
    double x = 0, y = 0, z = 0;
};

class LightView {
public:
    bool ortho = false;
    glm::dvec3 origin{0.0};  ///< the light's centre (perspective) or a point on the sun's origin plane
    glm::dvec3 axis{0, -1, 0}, e1{1, 0, 0}, e2{0, 0, 1};  ///< orthonormal: view direction and image axes
    double halfExtent = 1;   ///< tan of the half angle (perspective) or half the side in world units
    double zNear = 1e-6;     ///< geometry nearer than this is clipped
    double zFar = 1;         ///< the farthest receiver, for the reach of penumbra sheets
    int res = 1024;

    /// One texel in tangent units (perspective) or world units (orthographic).
    double texel() const { return 2 * halfExtent / res; }
    /// The world size of a texel at depth @p z.
    double texelWorld(double z) const { return ortho ? texel() : z * texel(); }
    /// Depth of @p p; projection is valid only for depth >= zNear.
    double depth(const glm::dvec3& p) const { return glm::dot(p - origin, axis); }
    ViewPoint project(const glm::dvec3& p) const;
    /// The value interpolated linearly across the image: 1/z (perspective) or z (orthographic).
    double linearDepth(double z) const { return ortho ? z : 1.0 / z; }
    double fromLinear(double v) const { return ortho ? v : 1.0 / v; }
    /// Depths closer than this at depth @p z are one layer of a DepthMap: 3 % of the depth
    /// (perspective) or 1 % of the view's width (orthographic).
    double layerGap(double z) const { return ortho ? 0.02 * halfExtent : 0.03 * z; }
};

/// @brief Where the blockers that can shadow a fitted view's receivers lie: a convex region
/// holding the hull of the light's bound and the receivers (every segment from a receiver to a
/// light point lies in it; for a sun, the receivers swept towards it along its cone of
/// directions), as half-spaces in the view's frame.
///
/// The view is fitted to the receivers' directions, but a blocker that only the light's
/// off-centre points see behind a receiver lies beside them: under a wide light the hull reaches
/// far beyond the receivers' directions from the centre (a blocker at depth z, for a receiver at
/// depth z_r, lies as far as the light's half-width times 1/z - 1/z_r beyond it, in tangent units).
/// A texel outside the view is never drawn, and the lookups then see light there. How far the
/// view must reach depends on where the blockers are, which is known only once they are read:
/// so the shadow pass measures, per triangle, how far out its part inside the hull lies
/// (extentNeeded()), and the light's view is fitted again, wider, when that lies outside it.
struct ShadowReach {
    glm::dvec3 origin{0.0}, axis{0, -1, 0}, e1{1, 0, 0}, e2{0, 0, 1};  ///< the view's frame
    bool ortho = false;
    double zNear = 0;                ///< perspective: parts nearer than the view's near plane are never drawn
    std::vector<glm::dvec4> planes;  ///< in frame coordinates q = (e1, e2, axis) . (p - origin): dot(xyz, q) <= w
    bool empty() const { return planes.empty(); }
    /// @brief The half extent (perspective: tangent; sun: world units) that @p view needs to hold
    /// the part of @p t inside the region; 0 when @p t lies inside the view or outside the region.
    double extentNeeded(const LightView& view, const Triangle& t) const;
};

/// @brief The views of light @p light: one perspective view fitted to the receivers' directions
/// from the light's centre when they lie within 70 degrees of their mean, else the six faces of a
/// cube at @p cubeResolution; a sun gets one orthographic view covering the receivers, grown by
/// the reach of its penumbrae. The views' set-up reads the receivers in parallel, in fixed blocks
/// (the same views for any thread count).
/// @param minimumExtent the fitted view's half extent is at least this (perspective: a tangent,
/// and beyond 70 degrees the cube is taken; sun: world units), as ShadowReach::extentNeeded() measured
/// it in the view made without it (the same axis and frame: they depend on the receivers only)
/// @param reach if set, receives the region of the fitted view's blockers (left empty for a cube)
std::vector<LightView> makeLightViews(const LightSamples& samples, int light, const ReceiverPoints& receivers, int resolution,
                                      int cubeResolution, double minimumExtent = 0, ShadowReach* reach = nullptr);

/// @brief The light's centre (w = 1) or central direction towards it (w = 0): the mean of its
/// bound's vertices.
glm::dvec3 lightCentre(const LightSamples& samples, int light);

/// @brief A layered depth map: per texel the nearest depths of up to `layers` surfaces, ascending
/// (+infinity where fewer were drawn). Layer 0 is the classic shadow map. Depths closer than the
/// view's layer gap to a kept one merge into it (the nearer wins), so the two faces of a thin
/// solid take one layer and the next layers hold the surfaces hidden behind it from the centre.
struct DepthMap {
    int res = 0;
    int layers = 1;
    std::vector<float> depth;  ///< layer-major: layer * res * res + y * res + x
    void reset(int resolution, int layerCount);
    float at(int x, int y, int layer = 0) const { return depth[(size_t(layer) * res + y) * res + x]; }
    /// True when some texel of @p layer holds a depth (is not +infinity).
    bool holdsSurface(int layer) const;
    /// Inserts depth @p z at texel @p index (y * res + x) with merge gap @p gap.
    void insert(size_t index, float z, float gap);
};

/// @brief Scan-converts @p chunk into @p map, texel centres inside or on a triangle's edges;
/// triangles are clipped at the near plane. Rows are split between threads and every band draws
/// the chunk's triangles in stream order, so the map does not depend on the thread count.
/// @param alpha when given, a cut-out triangle (an alpha id in its flags) covers only the texels
/// whose ray from the view meets an opaque part of it (AlphaTable::lookup(), nearest texel), the
/// same test as the exact methods' and the camera's; null draws cut-outs as opaque triangles.
void rasterizeDepth(const LightView& view, std::span<const Triangle> chunk, DepthMap& map, const AlphaTable* alpha = nullptr);

/// @brief True when every receiver of @p receivers projects into @p views: inside one view's
/// image, beyond its near plane, and (with @p withinFar) no deeper than its zFar.
bool viewsCover(const std::vector<LightView>& views, const ReceiverPoints& receivers, bool withinFar);

/// @brief Projects @p t's vertices, or returns false when one is nearer than zNear.
bool projectTriangle(const LightView& view, const Triangle& t, ViewPoint (&out)[3]);

}  // namespace penumbra
