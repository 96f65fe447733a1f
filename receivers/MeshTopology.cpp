#include "receivers/MeshTopology.h"

#include <algorithm>
#include <array>
#include <bit>
#include <numeric>

namespace penumbra {
namespace {

/// The bits of a coordinate with -0 folded onto +0, so that both weld together.
uint32_t coordinateBits(float x) { return x == 0.0f ? 0u : std::bit_cast<uint32_t>(x); }

}  // namespace

MeshTopology buildMeshTopology(const IndexedMesh& mesh) {
    MeshTopology topology;
    const size_t vertices = mesh.position.size(), triangles = mesh.triangleCount();

    // Weld: sort vertex ids by position bits; equal runs share the id of their run.
    std::vector<std::array<uint32_t, 3>> key(vertices);
    for (size_t v = 0; v < vertices; ++v)
        key[v] = {coordinateBits(mesh.position[v].x), coordinateBits(mesh.position[v].y), coordinateBits(mesh.position[v].z)};
    std::vector<uint32_t> order(vertices);
    std::iota(order.begin(), order.end(), 0u);
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return key[a] != key[b] ? key[a] < key[b] : a < b; });
    topology.weld.assign(vertices, 0);
    for (size_t i = 0; i < vertices; ++i) {
        if (i > 0 && key[order[i]] != key[order[i - 1]]) ++topology.welded;
        topology.weld[order[i]] = topology.welded;
    }
    if (vertices > 0) ++topology.welded;

    // Rings: the triangles around every welded vertex (counting sort, so in index order).
    topology.ringStart.assign(size_t(topology.welded) + 1, 0);
    for (uint32_t index : mesh.indices) ++topology.ringStart[topology.weld[index] + 1];
    std::partial_sum(topology.ringStart.begin(), topology.ringStart.end(), topology.ringStart.begin());
    topology.ring.resize(mesh.indices.size());
    std::vector<uint32_t> fill(topology.ringStart.begin(), topology.ringStart.end() - 1);
    for (size_t c = 0; c < mesh.indices.size(); ++c) topology.ring[fill[topology.weld[mesh.indices[c]]]++] = uint32_t(c / 3);

    // Edges: sorted by their welded end points; a run of exactly two triangles is a manifold edge.
    struct Edge {
        uint32_t lo, hi, edge;
    };
    std::vector<Edge> edges;
    edges.reserve(3 * triangles);
    for (size_t t = 0; t < triangles; ++t) {
        const uint32_t w[3] = {topology.weld[mesh.indices[3 * t]], topology.weld[mesh.indices[3 * t + 1]],
                               topology.weld[mesh.indices[3 * t + 2]]};
        if (w[0] == w[1] || w[1] == w[2] || w[0] == w[2]) continue;  // degenerate: no neighbours
        for (uint32_t k = 0; k < 3; ++k) {
            const uint32_t a = w[k], b = w[(k + 1) % 3];
            edges.push_back({std::min(a, b), std::max(a, b), uint32_t(3 * t + k)});
        }
    }
    std::sort(edges.begin(), edges.end(), [](const Edge& a, const Edge& b) {
        return a.lo != b.lo ? a.lo < b.lo : a.hi != b.hi ? a.hi < b.hi : a.edge < b.edge;
    });
    topology.across.assign(3 * triangles, kNoTriangle);
    for (size_t i = 0; i < edges.size();) {
        size_t j = i + 1;
        while (j < edges.size() && edges[j].lo == edges[i].lo && edges[j].hi == edges[i].hi) ++j;
        if (j - i == 2 && edges[i].edge / 3 != edges[i + 1].edge / 3) {
            topology.across[edges[i].edge] = edges[i + 1].edge / 3;
            topology.across[edges[i + 1].edge] = edges[i].edge / 3;
        }
        i = j;
    }
    return topology;
}

}  // namespace penumbra
