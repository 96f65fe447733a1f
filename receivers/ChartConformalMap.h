#pragma once
/// @file ChartConformalMap.h
/// @brief Least-squares conformal maps (Lévy, Petitjean, Ray & Maillot 2002) for lightmap charts:
/// a chart flattened so that angles are kept as well as possible, which unrolls curved charts
/// (a cylinder patch exactly) where a planar projection squeezes their sides by cos(tilt).
///
/// Each triangle in its own plane contributes the two residuals of the Cauchy-Riemann equations
/// of the map, weighted by its area; two chart vertices far apart are pinned where the planar
/// projection put them, and the least-squares problem is solved by conjugate gradients on the
/// normal equations (CGLS), started from the planar projection. The result is scaled so its
/// area equals the surface's (texel density is then right on average). Deterministic: one
/// chart is solved sequentially in a fixed order.

#include "receivers/ChartParameterization.h"

namespace penumbra {

/// @brief Replaces @p chart's uv by its least-squares conformal map.
/// @pre chart.uv holds a planar projection (projectChart()); chart.triangles of @p surface.
/// @return false, leaving @p chart unchanged, when the map turns a triangle over (or the solve
///         does not give finite coordinates); overlaps are for the caller to check.
bool conformalMap(const ChartSurface& surface, Chart& chart);

}  // namespace penumbra
