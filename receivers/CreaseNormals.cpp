#include "receivers/CreaseNormals.h"

#include "receivers/MeshTopology.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace penumbra {
namespace {

/// Unit face normals (zero for degenerate triangles) and each triangle's corner angles.
struct Faces {
    std::vector<glm::dvec3> normal;
    std::vector<double> angle;  ///< 3 per triangle
};

Faces faceGeometry(const IndexedMesh& mesh) {
    Faces faces;
    const size_t triangles = mesh.triangleCount();
    faces.normal.resize(triangles, glm::dvec3(0.0));
    faces.angle.resize(3 * triangles, 0.0);
    for (size_t t = 0; t < triangles; ++t) {
        glm::dvec3 p[3];
        for (int k = 0; k < 3; ++k) p[k] = glm::dvec3(mesh.position[mesh.indices[3 * t + k]]);
        const glm::dvec3 n = glm::cross(p[1] - p[0], p[2] - p[0]);
        const double length = glm::length(n);
        if (!(length > 0) || !std::isfinite(length)) continue;
        faces.normal[t] = n / length;
        for (int k = 0; k < 3; ++k) {
            const glm::dvec3 a = p[(k + 1) % 3] - p[k], b = p[(k + 2) % 3] - p[k];
            const double la = glm::length(a), lb = glm::length(b);
            if (la > 0 && lb > 0) faces.angle[3 * t + k] = std::acos(std::clamp(glm::dot(a, b) / (la * lb), -1.0, 1.0));
        }
    }
    return faces;
}

/// The corner of triangle @p f at welded vertex @p w (the first such corner).
int cornerAt(const IndexedMesh& mesh, const MeshTopology& topology, uint32_t f, uint32_t w) {
    for (int k = 0; k < 3; ++k)
        if (topology.weld[mesh.indices[3 * size_t(f) + k]] == w) return k;
    return 0;
}

/// The normal of corner @p c (triangle c / 3): faces around it within the crease, angle-weighted.
glm::vec3 cornerNormal(const IndexedMesh& mesh, const MeshTopology& topology, const Faces& faces, size_t c,
                       double creaseCos) {
    const uint32_t t = uint32_t(c / 3), w = topology.weld[mesh.indices[c]];
    const glm::dvec3 own = faces.normal[t];
    const bool degenerate = own == glm::dvec3(0.0);
    glm::dvec3 sum(0.0);
    for (uint32_t f : topology.around(w)) {
        const glm::dvec3 n = faces.normal[f];
        if (n == glm::dvec3(0.0) || (!degenerate && glm::dot(n, own) < creaseCos)) continue;
        sum += faces.angle[3 * size_t(f) + size_t(cornerAt(mesh, topology, f, w))] * n;
    }
    const double length = glm::length(sum);
    if (length > 0) return glm::vec3(sum / length);
    return glm::vec3(own);  // every neighbour beyond the crease and the corner's angle zero
}

}  // namespace

IndexedMesh withCreaseNormals(const IndexedMesh& mesh, double creaseDeg) {
    const MeshTopology topology = buildMeshTopology(mesh);
    const Faces faces = faceGeometry(mesh);
    // A crease of exactly 0 still smooths coplanar faces, whose normals agree only to roundoff.
    const double creaseCos = std::min(std::cos(creaseDeg * std::numbers::pi / 180.0), 1.0 - 1e-12);

    IndexedMesh out;
    out.name = mesh.name;
    out.indices.resize(mesh.indices.size());
    // Per input vertex, the output vertices made from it so far (one per distinct normal).
    std::vector<std::vector<uint32_t>> made(mesh.position.size());
    for (size_t c = 0; c < mesh.indices.size(); ++c) {
        const uint32_t v = mesh.indices[c];
        const glm::vec3 normal = cornerNormal(mesh, topology, faces, c, creaseCos);
        uint32_t index = kNoTriangle;
        for (uint32_t candidate : made[v])
            if (out.normal[candidate] == normal) index = candidate;
        if (index == kNoTriangle) {
            index = uint32_t(out.position.size());
            out.position.push_back(mesh.position[v]);
            out.normal.push_back(normal);
            if (!mesh.uv0.empty()) out.uv0.push_back(mesh.uv0[v]);
            if (!mesh.uv1.empty()) out.uv1.push_back(mesh.uv1[v]);
            made[v].push_back(index);
        }
        out.indices[c] = index;
    }
    return out;
}

}  // namespace penumbra
