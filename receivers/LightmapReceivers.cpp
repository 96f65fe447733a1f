#include "receivers/LightmapReceivers.h"

#include "stream/util/TexelIndex.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

double cross2(glm::dvec2 a, glm::dvec2 b) { return a.x * b.y - a.y * b.x; }

/// Barycentrics of @p p in triangle (a, b, c) (twice-area @p area2, non-zero).
glm::dvec3 barycentric(glm::dvec2 p, glm::dvec2 a, glm::dvec2 b, glm::dvec2 c, double area2) {
    double l0 = cross2(b - p, c - p) / area2, l1 = cross2(c - p, a - p) / area2;
    return {l0, l1, 1.0 - l0 - l1};
}

/// Barycentrics of the point of triangle (a, b, c) nearest to @p p, found on the nearest edge
/// when p is outside, so that the weights are exactly on the triangle (no extrapolation).
glm::dvec3 nearestOnTriangle(glm::dvec2 p, const glm::dvec2 (&v)[3], double area2) {
    glm::dvec3 l = barycentric(p, v[0], v[1], v[2], area2);
    if (l.x >= 0 && l.y >= 0 && l.z >= 0) return l;
    double best = INFINITY;
    glm::dvec3 result(1, 0, 0);
    for (int i = 0; i < 3; ++i) {
        int j = (i + 1) % 3;
        glm::dvec2 edge = v[j] - v[i];
        double length2 = glm::dot(edge, edge);
        double t = length2 > 0 ? std::clamp(glm::dot(p - v[i], edge) / length2, 0.0, 1.0) : 0.0;
        glm::dvec2 q = v[i] + t * edge;
        double d = glm::dot(p - q, p - q);
        if (d < best) {
            best = d;
            result = glm::dvec3(0.0);
            result[i] = 1.0 - t, result[j] = t;
        }
    }
    return result;
}

}  // namespace

const std::vector<glm::vec2>* lightmapUvs(const IndexedMesh& mesh) {
    if (!mesh.uv1.empty()) return &mesh.uv1;
    if (!mesh.uv0.empty()) return &mesh.uv0;
    return nullptr;
}

bool usableLightmapUvs(const IndexedMesh& mesh) {
    const std::vector<glm::vec2>* uv = lightmapUvs(mesh);
    if (!uv) return false;
    for (glm::vec2 x : *uv)
        if (!(x.x >= -kUvTolerance && x.x <= 1 + kUvTolerance && x.y >= -kUvTolerance && x.y <= 1 + kUvTolerance)) return false;
    double area = 0;
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        const glm::dvec2 a((*uv)[mesh.indices[3 * t]]), b((*uv)[mesh.indices[3 * t + 1]]), c((*uv)[mesh.indices[3 * t + 2]]);
        area += std::abs(cross2(b - a, c - a));
    }
    return area > 0;
}

double clippedTriangleArea(glm::dvec2 a, glm::dvec2 b, glm::dvec2 c, glm::dvec2 lo, glm::dvec2 hi) {
    // Sutherland-Hodgman against the four sides; a triangle gains at most one vertex per side.
    glm::dvec2 buffer[2][8];
    int count = 3;
    buffer[0][0] = a, buffer[0][1] = b, buffer[0][2] = c;
    int current = 0;
    for (int side = 0; side < 4 && count > 0; ++side) {
        const int axis = side / 2;
        const bool upper = side % 2;
        const double bound = upper ? hi[axis] : lo[axis];
        // Signed distance inside the half-plane (>= 0 inside).
        auto inside = [&](glm::dvec2 p) { return upper ? bound - p[axis] : p[axis] - bound; };
        const glm::dvec2* in = buffer[current];
        glm::dvec2* out = buffer[1 - current];
        int n = 0;
        for (int i = 0; i < count; ++i) {
            glm::dvec2 p = in[i], q = in[(i + 1) % count];
            double dp = inside(p), dq = inside(q);
            if (dp >= 0) out[n++] = p;
            if ((dp >= 0) != (dq >= 0)) {
                glm::dvec2 x = p + (q - p) * (dp / (dp - dq));
                x[axis] = bound;  // exactly on the side, whatever the rounding
                out[n++] = x;
            }
        }
        count = n, current = 1 - current;
    }
    double area2 = 0;
    for (int i = 0; i < count; ++i) area2 += cross2(buffer[current][i], buffer[current][(i + 1) % count]);
    return 0.5 * std::abs(area2);
}

LightmapLayout rasterizeLightmap(const IndexedMesh& mesh, int width, int height) {
    const std::vector<glm::vec2>& uv = *lightmapUvs(mesh);
    const size_t texels = size_t(width) * size_t(height);
    LightmapLayout layout;
    layout.width = width, layout.height = height;
    layout.coverage.assign(texels, 0.0f);
    std::vector<int64_t> owner(texels, -1);
    std::vector<uint8_t> ownerHasCentre(texels, 0), centres(texels, 0);

    const size_t triangles = mesh.triangleCount();
    for (size_t t = 0; t < triangles; ++t) {
        glm::dvec2 v[3];
        for (int k = 0; k < 3; ++k) {
            glm::vec2 x = uv[mesh.indices[3 * t + k]];
            v[k] = glm::dvec2(double(x.x) * width, double(x.y) * height);  // texel units
        }
        const double area2 = cross2(v[1] - v[0], v[2] - v[0]);
        const glm::dvec3 p0(mesh.position[mesh.indices[3 * t]]), p1(mesh.position[mesh.indices[3 * t + 1]]),
            p2(mesh.position[mesh.indices[3 * t + 2]]);
        const double world = 0.5 * glm::length(glm::cross(p1 - p0, p2 - p0));
        layout.surfaceArea += world;
        if (area2 == 0 || !std::isfinite(area2)) {
            layout.noUvArea += world, layout.noUvTriangles += world > 0;
            continue;
        }
        // The share of the triangle's UV area inside the map is the share of its surface baked.
        const double inside = clippedTriangleArea(v[0], v[1], v[2], glm::dvec2(0.0), glm::dvec2(width, height));
        layout.outsideArea += world * std::max(0.0, 1.0 - inside / (0.5 * std::abs(area2)));
        const glm::dvec2 lo = glm::min(glm::min(v[0], v[1]), v[2]), hi = glm::max(glm::max(v[0], v[1]), v[2]);
        // Texels whose square can overlap the bounds; the part of a triangle outside [0, 1]^2 is
        // dropped (lightmaps do not wrap).
        // Clamped before the conversion: a file's UVs may lie anywhere, and int() of a value
        // past its range is undefined (x86 gives INT_MIN, a loop over billions of texels).
        const int x0 = clampedTexel(std::floor(lo.x), 0, width), y0 = clampedTexel(std::floor(lo.y), 0, height);
        const int x1 = clampedTexel(std::ceil(hi.x) - 1, -1, width - 1), y1 = clampedTexel(std::ceil(hi.y) - 1, -1, height - 1);
        for (int y = y0; y <= y1; ++y) {
            for (int x = x0; x <= x1; ++x) {
                const double covered = clippedTriangleArea(v[0], v[1], v[2], glm::dvec2(x, y), glm::dvec2(x + 1, y + 1));
                if (!(covered > 0)) continue;
                const size_t texel = size_t(y) * width + x;
                layout.coverage[texel] += float(covered);
                const glm::dvec3 l = barycentric(glm::dvec2(x + 0.5, y + 0.5), v[0], v[1], v[2], area2);
                const bool hasCentre = l.x >= 0 && l.y >= 0 && l.z >= 0;
                // Strictly inside: a centre on an edge shared by two triangles is not an overlap.
                if (l.x > 0 && l.y > 0 && l.z > 0 && centres[texel] < 255) ++centres[texel];
                if (owner[texel] < 0 || (hasCentre && !ownerHasCentre[texel])) {
                    owner[texel] = int64_t(t);
                    ownerHasCentre[texel] = hasCentre;
                }
            }
        }
    }

    const bool shading = !mesh.normal.empty();
    for (size_t texel = 0; texel < texels; ++texel) {
        layout.coverage[texel] = std::min(layout.coverage[texel], 1.0f);
        if (centres[texel] > 1) ++layout.overlapping;
        if (owner[texel] < 0) continue;
        const size_t t = size_t(owner[texel]);
        const uint32_t i[3] = {mesh.indices[3 * t], mesh.indices[3 * t + 1], mesh.indices[3 * t + 2]};
        glm::dvec2 v[3];
        for (int k = 0; k < 3; ++k) v[k] = glm::dvec2(uv[i[k]]) * glm::dvec2(width, height);
        const glm::dvec2 centre(double(texel % width) + 0.5, double(texel / width) + 0.5);
        const glm::dvec3 l = nearestOnTriangle(centre, v, cross2(v[1] - v[0], v[2] - v[0]));

        const glm::dvec3 p0(mesh.position[i[0]]), p1(mesh.position[i[1]]), p2(mesh.position[i[2]]);
        glm::dvec3 normal(0.0);
        if (shading)
            normal = l.x * glm::dvec3(mesh.normal[i[0]]) + l.y * glm::dvec3(mesh.normal[i[1]]) +
                     l.z * glm::dvec3(mesh.normal[i[2]]);
        if (!(glm::length(normal) > 1e-12)) normal = glm::cross(p1 - p0, p2 - p0);  // geometric fallback
        const double length = glm::length(normal);
        layout.receivers.position.emplace_back(l.x * p0 + l.y * p1 + l.z * p2);
        layout.receivers.normal.emplace_back(length > 0 ? normal / length : glm::dvec3(0.0));
        layout.texel.push_back(uint32_t(texel));
        layout.triangle.push_back(uint32_t(t));
    }
    return layout;
}

int lightmapSideForDensity(const IndexedMesh& mesh, double texelsPerUnit) {
    const std::vector<glm::vec2>& uv = *lightmapUvs(mesh);
    double world = 0, texture = 0;
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
        const uint32_t a = mesh.indices[3 * t], b = mesh.indices[3 * t + 1], c = mesh.indices[3 * t + 2];
        world += 0.5 * glm::length(glm::cross(glm::dvec3(mesh.position[b] - mesh.position[a]),
                                              glm::dvec3(mesh.position[c] - mesh.position[a])));
        texture += 0.5 * std::abs(cross2(glm::dvec2(uv[b] - uv[a]), glm::dvec2(uv[c] - uv[a])));
    }
    if (!(texture > 0)) return 0;
    const double side = std::ceil(texelsPerUnit * std::sqrt(world / texture));
    return int(std::clamp(side, 1.0, double(INT32_MAX)));
}

void dilateLightmap(std::span<std::vector<float>* const> channels, std::vector<uint8_t>& filled, int width, int height,
                    int rings) {
    std::vector<size_t> ring;
    std::vector<float> values;  // per ring texel, one value per channel
    const size_t nc = channels.size();
    for (int r = 0; r < rings; ++r) {
        ring.clear(), values.clear();
        for (int y = 0; y < height; ++y) {
            for (int x = 0; x < width; ++x) {
                const size_t texel = size_t(y) * width + x;
                if (filled[texel]) continue;
                int neighbours = 0;
                const size_t first = values.size();
                values.resize(first + nc, 0.0f);
                for (int dy = -1; dy <= 1; ++dy) {
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int nx = x + dx, ny = y + dy;
                        if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= width || ny >= height) continue;
                        const size_t n = size_t(ny) * width + nx;
                        if (!filled[n]) continue;
                        ++neighbours;
                        for (size_t c = 0; c < nc; ++c) values[first + c] += (*channels[c])[n];
                    }
                }
                if (neighbours == 0) {
                    values.resize(first);
                    continue;
                }
                for (size_t c = 0; c < nc; ++c) values[first + c] /= float(neighbours);
                ring.push_back(texel);
            }
        }
        if (ring.empty()) break;
        // Applied after the whole ring is found, so each ring reads only the previous rings.
        for (size_t k = 0; k < ring.size(); ++k) {
            filled[ring[k]] = 1;
            for (size_t c = 0; c < nc; ++c) (*channels[c])[ring[k]] = values[k * nc + c];
        }
    }
}

}  // namespace penumbra
