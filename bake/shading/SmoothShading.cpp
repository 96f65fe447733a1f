#include "bake/shading/SmoothShading.h"

#include "receivers/CameraReceivers.h"
#include "stream/util/BandLists.h"
#include "stream/Triangle.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <numeric>

namespace penumbra {

glm::dvec3 LightDirection::at(const glm::dvec3& p) const {
    if (glm::dot(towardLight, towardLight) > 0) return towardLight;
    glm::dvec3 d = point - p;
    double len = glm::length(d);
    return len > 0 ? d / len : glm::dvec3(0.0);
}

std::vector<LightDirection> lightDirections(const std::vector<LightDesc>& lights) {
    std::vector<LightDirection> out;
    for (const LightDesc& l : lights) {
        LightDirection d;
        if (l.type == LightType::Sun) d.towardLight = -glm::normalize(l.direction);
        else if (l.type == LightType::Polygon)
            d.point = std::accumulate(l.polygon.begin(), l.polygon.end(), glm::dvec3(0.0)) / double(l.polygon.size());
        else d.point = l.center;
        out.push_back(d);
    }
    return out;
}

double smoothShadingFactor(double lf, double lbend) {
    if (!(lf > 1e-9)) return 0.0;
    double alpha = std::clamp(3.0 * lbend, 0.0, 1.0);
    double s = alpha * lf + (1.0 - alpha) * lbend;
    return std::clamp(s / lf, 0.0, 1.0);
}

PositionKey VertexBend::keyOf(const glm::vec3& p) {
    // +0 and -0 are the same vertex.
    auto bits = [](float f) { return std::bit_cast<uint32_t>(f == 0.f ? 0.f : f); };
    return {bits(p.x), bits(p.y), bits(p.z)};
}

VertexBend::VertexBend(std::span<const std::array<glm::vec3, 3>> triangles, std::span<const glm::vec3> normals,
                       std::vector<LightDirection> lights)
    : lights_(std::move(lights)) {
    addTriangles(triangles, normals);
}

uint32_t VertexBend::slotOf(const glm::vec3& v, float sign, const glm::vec3& owner) {
    static_assert(kNone == PositionIndex::kEmpty, "a new position's slot list starts empty");
    uint32_t& latest = index_.findOrInsert(keyOf(v));
    for (uint32_t s = latest; s != kNone; s = next_[s])
        if (owner_[s] == owner) return s;  // the same face (or an exactly parallel one) owns it already
    const uint32_t slot = uint32_t(sign_.size());
    vertex_.push_back(v);
    owner_.push_back(owner);
    sign_.push_back(sign);
    next_.push_back(latest);
    latest = slot;
    bend_.insert(bend_.end(), lights_.size(), 1.f);
    return slot;
}

std::array<uint32_t, 3> VertexBend::cornersOf(const std::array<glm::vec3, 3>& t, float sign) {
    glm::dvec3 n = glm::cross(glm::dvec3(t[1] - t[0]), glm::dvec3(t[2] - t[0]));
    const double len = glm::length(n);
    const glm::vec3 owner(len > 0 ? double(sign) * n / len : glm::dvec3(0.0));
    return {slotOf(t[0], sign, owner), slotOf(t[1], sign, owner), slotOf(t[2], sign, owner)};
}

void VertexBend::addTriangles(std::span<const std::array<glm::vec3, 3>> triangles, std::span<const glm::vec3> normals) {
    for (size_t r = 0; r < triangles.size(); ++r) {
        const auto& t = triangles[r];
        glm::dvec3 n = glm::cross(glm::dvec3(t[1] - t[0]), glm::dvec3(t[2] - t[0]));
        corners_.push_back(cornersOf(t, glm::dot(n, glm::dvec3(normals[r])) < 0 ? -1.f : 1.f));
    }
}

std::vector<uint32_t> VertexBend::sortedByTriangle(const std::vector<uint64_t>& ids) {
    // A stable LSD radix sort, one BandLists counting sort per 11 bits of the largest id: a
    // serial std::stable_sort of FLOWERS' 1.2 M receivers took 70 ms at the end of the scan.
    const uint64_t mask = ~CameraRasterizer::kFlippedBit;
    uint64_t largest = 0;
    for (const uint64_t id : ids) largest = std::max(largest, id & mask);
    std::vector<uint32_t> order(ids.size()), other(ids.size());
    std::iota(order.begin(), order.end(), 0u);
    constexpr int kBits = 11;
    BandLists digits;
    for (int shift = 0; shift < 64 && (largest >> shift) != 0; shift += kBits) {
        digits.build(1 << kBits, order.size(), [&](size_t i, int& lo, int& hi) {
            lo = hi = int((ids[order[i]] & mask) >> shift & ((1u << kBits) - 1));
        });
        for (size_t k = 0; k < order.size(); ++k) other[k] = order[digits.members[k]];
        order.swap(other);
    }
    return order;
}

void VertexBend::expectTriangleIds(std::vector<uint64_t> ids) {
    firstWaiting_ = corners_.size();
    corners_.resize(corners_.size() + ids.size(), {kNone, kNone, kNone});
    ids_ = std::move(ids);
    order_ = sortedByTriangle(ids_);
    cursor_ = 0, seen_ = 0;
}

void VertexBend::recover(std::span<const Triangle> chunk) {
    const uint64_t mask = ~CameraRasterizer::kFlippedBit;
    for (; cursor_ < order_.size(); ++cursor_) {
        const uint32_t r = order_[cursor_];
        const uint64_t id = ids_[r] & mask;
        if (id >= seen_ + chunk.size()) break;
        // Receivers on one triangle are neighbours in the id order (six per visible triangle on
        // SPONZA-LIKE), and cornersOf() would find the same three slots again, one hash probe
        // each: reuse them (the flip bit is part of the comparison, as it is of the slots).
        if (cursor_ > 0 && ids_[order_[cursor_ - 1]] == ids_[r]) {
            corners_[firstWaiting_ + r] = corners_[firstWaiting_ + order_[cursor_ - 1]];
            continue;
        }
        const Triangle& t = chunk[id - seen_];
        const float sign = ids_[r] & CameraRasterizer::kFlippedBit ? -1.f : 1.f;
        corners_[firstWaiting_ + r] = cornersOf({t.v[0], t.v[1], t.v[2]}, sign);
    }
    seen_ += chunk.size();
    if (cursor_ == order_.size()) {  // all found: free the waiting list (`= {}` would keep the capacity)
        ids_ = std::vector<uint64_t>();
        order_ = std::vector<uint32_t>();
    }
}

void VertexBend::buildFilter() {
    // About 16 bits per visible position: a face vertex that is not visible (nearly all of them
    // in a big scene) is rejected by one bit test with a false-positive rate near 1/16, instead
    // of a hash-map probe that misses the cache.
    size_t bits = 1 << 16;
    while (bits < 16 * index_.size()) bits <<= 1;
    filter_.assign(bits / 64, 0);
    filterMask_ = bits - 1;
    for (const PositionIndex::Entry& entry : index_.entries()) {
        if (entry.value == PositionIndex::kEmpty) continue;
        const uint64_t h = entry.key.hash() & filterMask_;
        filter_[h >> 6] |= 1ull << (h & 63);
    }
    filterSize_ = index_.size();
}

void VertexBend::add(std::span<const Triangle> chunk) {
    if (filterSize_ != index_.size() || filter_.empty()) buildFilter();
    const size_t L = lights_.size();
    cosines_.resize(L);
    for (const Triangle& tri : chunk) {
        uint32_t first[3];
        bool any = false;
        for (int i = 0; i < 3; ++i) {
            first[i] = kNone;
            const PositionKey key = keyOf(tri.v[i]);
            const uint64_t h = key.hash() & filterMask_;
            if (!(filter_[h >> 6] >> (h & 63) & 1)) continue;
            first[i] = index_.find(key);
            any |= first[i] != kNone;
        }
        if (!any) continue;
        glm::dvec3 n = glm::cross(glm::dvec3(tri.v[1] - tri.v[0]), glm::dvec3(tri.v[2] - tri.v[0]));
        double len = glm::length(n);
        if (!(len > 0) || !std::isfinite(len)) continue;
        n /= len;
        for (int i = 0; i < 3; ++i) {
            // Each light's cosine at the vertex, once for all its slots (a vertex of FLOWERS has
            // about three, one per surface that meets there).
            bool lit = false;
            for (uint32_t slot = first[i]; slot != kNone; slot = next_[slot]) {
                // A face across a crease (normals more than kCreaseDeg apart) is another surface.
                if (sign_[slot] * glm::dot(n, glm::dvec3(owner_[slot])) < kCreaseCos) continue;
                if (!lit) {
                    for (size_t l = 0; l < L; ++l) cosines_[l] = glm::dot(lights_[l].at(glm::dvec3(tri.v[i])), n);
                    lit = true;
                }
                for (size_t l = 0; l < L; ++l) bend_[slot * L + l] = std::min(bend_[slot * L + l], float(sign_[slot] * cosines_[l]));
            }
        }
    }
}

double VertexBend::factor(size_t r, const glm::dvec3& position, const glm::dvec3& normal, int light) const {
    const auto& c = corners_[r];
    if (c[0] == kNone) return 1.0;
    const glm::vec3 t[3] = {vertex_[c[0]], vertex_[c[1]], vertex_[c[2]]};
    const size_t L = lights_.size();
    // Barycentric coordinates of the receiver in its triangle (it lies in the triangle's plane).
    glm::dvec3 a(t[0]), e1 = glm::dvec3(t[1]) - a, e2 = glm::dvec3(t[2]) - a, q = position - a;
    double d11 = glm::dot(e1, e1), d12 = glm::dot(e1, e2), d22 = glm::dot(e2, e2);
    double q1 = glm::dot(q, e1), q2 = glm::dot(q, e2), det = d11 * d22 - d12 * d12;
    double b1 = det > 0 ? std::clamp((d22 * q1 - d12 * q2) / det, 0.0, 1.0) : 1.0 / 3;
    double b2 = det > 0 ? std::clamp((d11 * q2 - d12 * q1) / det, 0.0, 1.0 - b1) : 1.0 / 3;
    double w[3] = {1.0 - b1 - b2, b1, b2};
    double bend = 0;
    for (int i = 0; i < 3; ++i) bend += w[i] * bend_[c[i] * L + size_t(light)];
    double lf = glm::dot(lights_[size_t(light)].at(position), normal);
    return smoothShadingFactor(lf, bend);
}

uint64_t VertexBend::boundBytes(uint64_t receivers, uint64_t triangles, size_t lights) {
    // Per receiver: its corner slots (12), its triangle id and place in the id order while they
    // are recovered (12). Per slot, at most three per distinct triangle: its position's entry in
    // the index (at most one per slot, at its peak while the index grows), next/vertex/owner/
    // sign/bend (32 + 4 per light, twice for vector growth) and 16 filter bits, with the
    // filter's 8 KiB floor.
    const uint64_t slots = 3 * std::min(receivers, triangles);
    return receivers * 24 + slots * (PositionIndex::kPeakBytesPerKey + 2 * (32 + 4 * uint64_t(lights)) + 2) + (8u << 10);
}

uint64_t VertexBend::plannedBytes() const {
    const uint64_t mask = ~CameraRasterizer::kFlippedBit;
    uint64_t distinct = 0;
    for (size_t i = 0; i < order_.size(); ++i) distinct += i == 0 || (ids_[order_[i]] & mask) != (ids_[order_[i - 1]] & mask);
    return boundBytes(corners_.size(), distinct, lights_.size());
}

uint64_t VertexBend::plannedBytes(uint64_t receivers, uint64_t triangles) const {
    if (receivers <= corners_.size()) return plannedBytes();
    // Appending may grow the corner vector to twice the receivers' corners.
    return boundBytes(receivers, triangles, lights_.size()) + sizeof(corners_[0]) * receivers;
}

uint64_t VertexBend::bytes() const {
    return corners_.capacity() * sizeof(corners_[0]) + index_.bytes() +
           (vertex_.capacity() + owner_.capacity()) * sizeof(glm::vec3) + sign_.capacity() * sizeof(float) +
           next_.capacity() * sizeof(uint32_t) + bend_.capacity() * sizeof(float) +
           ids_.capacity() * sizeof(uint64_t) + order_.capacity() * sizeof(uint32_t) +
           filter_.capacity() * sizeof(uint64_t);
}

}  // namespace penumbra
