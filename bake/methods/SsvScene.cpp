#include "bake/methods/SsvScene.h"

#include "stream/util/Progress.h"

#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <tuple>

namespace penumbra {
namespace {

double maxAbs(const glm::dvec3& p) { return std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}); }

/// A face corner keyed by its exact position (+0 for -0, so both zeros are one vertex).
struct Corner {
    double x, y, z;
    uint32_t index;  ///< face * 3 + corner
    bool operator<(const Corner& o) const { return std::tie(x, y, z, index) < std::tie(o.x, o.y, o.z, o.index); }
    bool samePlace(const Corner& o) const { return x == o.x && y == o.y && z == o.z; }
};

struct HalfEdge {
    uint32_t lo, hi;  ///< vertex ids, lo < hi
    uint32_t index;   ///< face * 3 + edge
    bool operator<(const HalfEdge& o) const { return std::tie(lo, hi, index) < std::tie(o.lo, o.hi, o.index); }
};

}  // namespace

uint64_t SsvLight::bytes() const {
    return side.capacity() + potential.capacity() + edges.capacity() * sizeof(SsvEdge) + tree.bytes();
}

namespace {
/// @p params with the byte limit the plan reserves for a tree over @p triangles, unless given.
KdParams treeParams(KdParams params, size_t triangles) {
    if (!params.maxBytes) params.maxBytes = triangles * SsvScene::kTreeBytesPerTriangle;
    return params;
}
}  // namespace

SsvScene::SsvScene(std::span<const Triangle> triangles, const LightSamples& samples, const ReceiverEpsilon& epsilon,
                   const KdBox& receiverBox, const KdParams& params) {
    Stopwatch watch;
    faces_.reserve(triangles.size());
    KdBox scene = receiverBox;
    for (const Triangle& tri : triangles) {
        BlockerTriangle b = BlockerTriangle::from(tri);
        if (!b.valid) continue;
        for (const glm::dvec3& v : b.v) scene.add(v);
        if (b.alpha != 0) {
            alpha_.push_back(b);
            continue;
        }
        SsvFace f;
        f.t = b;
        faces_.push_back(f);
    }
    stats_.faces = faces_.size(), stats_.alphaFaces = alpha_.size();
    std::vector<KdItem> alphaItems(alpha_.size());
    for (size_t i = 0; i < alpha_.size(); ++i) {
        for (const glm::dvec3& v : alpha_[i].v) alphaItems[i].box.add(v);
        alphaItems[i].id = uint32_t(i), alphaItems[i].kind = kSsvTriangleItem;
    }
    alphaTree_.build(std::move(alphaItems), treeParams(params, alpha_.size()));
    if (!scene.empty()) sceneSize_ = std::max(1e-300, glm::length(scene.hi - scene.lo));
    findAdjacency();
    lights_.resize(size_t(samples.lightCount()));
    for (int l = 0; l < samples.lightCount(); ++l) classify(l, samples, epsilon, receiverBox, params);
    stats_.buildSeconds = watch.seconds();
}

void SsvScene::findAdjacency() {
    const size_t n = faces_.size();
    std::vector<uint32_t> vertex(3 * n);
    {
        std::vector<Corner> corners(3 * n);
        tbb::parallel_for(size_t(0), n, [&](size_t f) {
            for (int c = 0; c < 3; ++c) {
                const glm::dvec3& p = faces_[f].t.v[c];
                corners[3 * f + c] = {p.x + 0.0, p.y + 0.0, p.z + 0.0, uint32_t(3 * f + c)};
            }
        });
        tbb::parallel_sort(corners.begin(), corners.end());
        uint32_t id = 0;
        for (size_t i = 0; i < corners.size(); ++i) {
            if (i > 0 && !corners[i].samePlace(corners[i - 1])) ++id;
            vertex[corners[i].index] = id;
        }
        stats_.vertices = corners.empty() ? 0 : id + 1;
    }
    std::vector<HalfEdge> halves(3 * n);
    tbb::parallel_for(size_t(0), n, [&](size_t f) {
        for (int e = 0; e < 3; ++e) {
            const uint32_t a = vertex[3 * f + e], b = vertex[3 * f + (e + 1) % 3];
            halves[3 * f + e] = {std::min(a, b), std::max(a, b), uint32_t(3 * f + e)};
        }
    });
    std::vector<uint32_t>().swap(vertex);
    tbb::parallel_sort(halves.begin(), halves.end());
    for (size_t i = 0; i < halves.size();) {
        size_t j = i + 1;
        while (j < halves.size() && halves[j].lo == halves[i].lo && halves[j].hi == halves[i].hi) ++j;
        if (j - i == 2) {
            const uint32_t f = halves[i].index / 3, g = halves[i + 1].index / 3;
            const uint8_t e = uint8_t(halves[i].index % 3), ge = uint8_t(halves[i + 1].index % 3);
            faces_[f].neighbor[e] = g, faces_[f].neighborEdge[e] = ge;
            faces_[g].neighbor[ge] = f, faces_[g].neighborEdge[ge] = e;
            ++stats_.sharedEdges;
        } else {
            stats_.boundaryEdges += j - i;
        }
        i = j;
    }
}

void SsvScene::classify(int li, const LightSamples& samples, const ReceiverEpsilon& epsilon, const KdBox& receiverBox,
                        const KdParams& params) {
    SsvLight& light = lights_[size_t(li)];
    const ConvexBound& bound = samples.lightBounds[size_t(li)];
    const double w = bound.w;
    // The band radius needs the largest eps(r) and |l - w r| over every receiver and light point.
    double epsMax = epsilon.at(glm::dvec3(0.0)), maxLength = 0;
    if (!receiverBox.empty()) {
        epsMax = std::max(epsilon.at(receiverBox.lo), epsilon.at(receiverBox.hi));
        for (const glm::dvec3& v : bound.vertices)
            for (int c = 0; c < 8; ++c) {
                const glm::dvec3 corner(c & 1 ? receiverBox.hi.x : receiverBox.lo.x, c & 2 ? receiverBox.hi.y : receiverBox.lo.y,
                                        c & 4 ? receiverBox.hi.z : receiverBox.lo.z);
                maxLength = std::max(maxLength, glm::length(v - w * corner));
            }
    }
    // Beyond this radius a face is cast per sample: its band triangles would be looked up from too far.
    const double radiusCap = 0.01 * sceneSize_;
    const size_t n = faces_.size();
    light.side.assign(n, 0);
    std::vector<double> radius(n, 0.0);
    tbb::parallel_for(size_t(0), n, [&](size_t f) {
        const BlockerTriangle& t = faces_[f].t;
        double lowest = INFINITY;
        int positive = 0, negative = 0;
        for (const glm::dvec3& v : bound.vertices) {
            const double s = t.side(v, w), tol = 1e-9 * (maxAbs(v) + w * maxAbs(t.v[0]));
            positive += s > tol, negative += s < -tol;
            lowest = std::min(lowest, std::abs(s));
        }
        const int count = int(bound.vertices.size());
        if (positive != count && negative != count) return;
        radius[f] = epsMax * maxLength / lowest;
        if (!(radius[f] <= radiusCap)) return;
        light.side[f] = int8_t(positive == count ? 1 : -1);
    });
    light.potential.assign(n, 0);
    for (size_t f = 0; f < n; ++f) {
        const SsvFace& face = faces_[f];
        for (int e = 0; e < 3; ++e) {
            const uint32_t g = face.neighbor[e];
            bool potential = g == kNoFace || light.side[f] == 0 || light.side[g] == 0;
            if (!potential) {
                // The rule's edge tests of the two faces cancel when their orientations along the
                // edge, o = s * (direction of the edge in the face), are opposite.
                const bool sameDirection = faces_[g].t.v[face.neighborEdge[e]] == face.t.v[e];
                const bool cancel = sameDirection ? light.side[f] == -light.side[g] : light.side[f] == light.side[g];
                potential = !cancel;
            }
            if (!potential) continue;
            light.potential[f] |= uint8_t(1u << e);
            if (g == kNoFace || f < g) {
                SsvEdge edge;
                edge.face[0] = uint32_t(f), edge.edge[0] = uint8_t(e);
                if (g != kNoFace) edge.face[1] = g, edge.edge[1] = face.neighborEdge[e];
                light.edges.push_back(edge);
            }
        }
    }
    light.edges.shrink_to_fit();
    std::vector<KdItem> items(light.edges.size() + n);
    tbb::parallel_for(size_t(0), light.edges.size(), [&](size_t i) {
        const SsvFace& face = faces_[light.edges[i].face[0]];
        const int e = light.edges[i].edge[0];
        KdItem& item = items[i];
        item.box.add(face.t.v[e]), item.box.add(face.t.v[(e + 1) % 3]);
        item.id = uint32_t(i), item.kind = kSsvEdgeItem;
    });
    tbb::parallel_for(size_t(0), n, [&](size_t f) {
        KdItem& item = items[light.edges.size() + f];
        for (const glm::dvec3& v : faces_[f].t.v) item.box.add(v);
        item.id = uint32_t(f);
        if (light.side[f] == 0) {
            item.kind = kSsvStraddlerItem;
        } else {
            item.kind = kSsvTriangleItem;
            item.box.lo -= glm::dvec3(radius[f]), item.box.hi += glm::dvec3(radius[f]);
        }
    });
    for (size_t f = 0; f < n; ++f) {
        if (light.side[f] == 0) ++light.straddlers;
        else light.bandRadiusMax = std::max(light.bandRadiusMax, radius[f]);
    }
    light.tree.build(std::move(items), treeParams(params, n));
}

uint64_t SsvScene::bytes() const {
    uint64_t b = faces_.capacity() * sizeof(SsvFace) + alpha_.capacity() * sizeof(BlockerTriangle) + alphaTree_.bytes();
    for (const SsvLight& l : lights_) b += l.bytes();
    return b;
}

}  // namespace penumbra
