#include "receivers/ChartSegmentation.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>

namespace penumbra {
namespace {

constexpr uint32_t kAbsent = ~0u, kFree = ~0u - 1;

double cosDeg(double degrees) { return std::cos(std::min(degrees, 180.0) * std::numbers::pi / 180.0); }

/// One chart while segmenting: its triangles, area, normal sum and a lower bound of
/// dot(n_t, mean) over its triangles (kept so that merges into a large chart need not revisit it).
struct Growing {
    std::vector<uint32_t> triangles;
    double area = 0;
    glm::dvec3 sum{0.0};
    double minDot = 1;
    bool alive = true;
    glm::dvec3 mean() const {
        const double length = glm::length(sum);
        return length > 0 ? sum / length : glm::dvec3(0, 0, 1);
    }
};

class Segmenter {
public:
    Segmenter(const ChartSurface& surface, std::span<const uint32_t> triangles)
        : s_(surface), chartOf_(surface.normal.size(), kAbsent) {
        for (uint32_t t : triangles) chartOf_[t] = kFree;
        triangles_.assign(triangles.begin(), triangles.end());
    }

    void grow(double coneCos) {
        std::vector<uint32_t> seeds;
        for (uint32_t t : triangles_)
            if (!s_.degenerate(t)) seeds.push_back(t);
        std::sort(seeds.begin(), seeds.end(), [&](uint32_t a, uint32_t b) { return s_.area[a] != s_.area[b] ? s_.area[a] > s_.area[b] : a < b; });
        for (uint32_t seed : seeds)
            if (chartOf_[seed] == kFree) growFrom(seed, coneCos);
        attachDegenerate();
    }

    void merge(double smallArea, double limitCos) {
        std::vector<uint32_t> order(charts_.size());
        std::iota(order.begin(), order.end(), 0u);
        std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
            return charts_[a].area != charts_[b].area ? charts_[a].area < charts_[b].area : a < b;
        });
        for (uint32_t c : order)
            if (charts_[c].alive && charts_[c].area < smallArea) mergeIntoNeighbour(c, limitCos);
    }

    std::vector<std::vector<uint32_t>> result() {
        std::vector<std::vector<uint32_t>> charts;
        for (Growing& chart : charts_) {
            if (!chart.alive) continue;
            std::sort(chart.triangles.begin(), chart.triangles.end());
            charts.push_back(std::move(chart.triangles));
        }
        return charts;
    }

private:
    uint32_t newChart() {
        charts_.emplace_back();
        return uint32_t(charts_.size() - 1);
    }

    void add(uint32_t c, uint32_t t) {
        chartOf_[t] = c;
        Growing& chart = charts_[c];
        chart.triangles.push_back(t);
        chart.area += s_.area[t];
        chart.sum += s_.area[t] * s_.normal[t];
    }

    void growFrom(uint32_t seed, double coneCos) {
        const uint32_t c = newChart();
        add(c, seed);
        // Breadth first: the chart's triangle list is the queue.
        for (size_t head = 0; head < charts_[c].triangles.size(); ++head) {
            const uint32_t t = charts_[c].triangles[head];
            for (int k = 0; k < 3; ++k) {
                const uint32_t u = s_.topology.across[3 * size_t(t) + k];
                if (u == kNoTriangle || chartOf_[u] != kFree) continue;
                if (glm::dot(s_.normal[u], charts_[c].mean()) >= coneCos) add(c, u);
            }
        }
        charts_[c].minDot = exactMinDot(charts_[c], charts_[c].mean());
    }

    void attachDegenerate() {
        for (uint32_t t : triangles_) {
            if (chartOf_[t] != kFree) continue;
            uint32_t chart = kAbsent;
            for (int k = 0; k < 3 && chart == kAbsent; ++k)
                for (uint32_t f : s_.topology.around(s_.topology.weld[s_.mesh.indices[3 * size_t(t) + k]]))
                    if (chartOf_[f] < kFree) {
                        chart = chartOf_[f];
                        break;
                    }
            add(chart == kAbsent ? newChart() : chart, t);
        }
    }

    double exactMinDot(const Growing& chart, const glm::dvec3& mean) const {
        double lowest = 1;
        for (uint32_t t : chart.triangles)
            if (!s_.degenerate(t)) lowest = std::min(lowest, glm::dot(s_.normal[t], mean));
        return lowest;
    }

    /// Whether every triangle of @p chart is within the limit of @p mean; also returns the
    /// bound of dot(n_t, mean) it established.
    bool within(const Growing& chart, const glm::dvec3& mean, double limitCos, double& bound) const {
        bound = chart.minDot - glm::length(mean - chart.mean());  // |n| = 1: dot moves by at most |dm|
        if (bound >= limitCos) return true;
        bound = exactMinDot(chart, mean);
        return bound >= limitCos;
    }

    void mergeIntoNeighbour(uint32_t c, double limitCos) {
        std::map<uint32_t, double> border;  // neighbouring chart -> shared edge length
        for (uint32_t t : charts_[c].triangles) {
            for (int k = 0; k < 3; ++k) {
                const uint32_t u = s_.topology.across[3 * size_t(t) + k];
                if (u == kNoTriangle || chartOf_[u] >= kFree || chartOf_[u] == c) continue;
                const glm::vec3& a = s_.mesh.position[s_.mesh.indices[3 * size_t(t) + k]];
                const glm::vec3& b = s_.mesh.position[s_.mesh.indices[3 * size_t(t) + (k + 1) % 3]];
                border[chartOf_[u]] += glm::length(glm::dvec3(b) - glm::dvec3(a));
            }
        }
        std::vector<std::pair<uint32_t, double>> candidates(border.begin(), border.end());
        std::stable_sort(candidates.begin(), candidates.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
        for (const auto& [n, length] : candidates) {
            Growing &small = charts_[c], &large = charts_[n];
            const glm::dvec3 sum = small.sum + large.sum;
            const glm::dvec3 mean = glm::length(sum) > 0 ? glm::normalize(sum) : glm::dvec3(0, 0, 1);
            double boundSmall = 1, boundLarge = 1;
            if (!within(small, mean, limitCos, boundSmall) || !within(large, mean, limitCos, boundLarge)) continue;
            for (uint32_t t : small.triangles) chartOf_[t] = n;
            large.triangles.insert(large.triangles.end(), small.triangles.begin(), small.triangles.end());
            large.area += small.area, large.sum = sum, large.minDot = std::min(boundSmall, boundLarge);
            small = Growing{};
            small.alive = false;
            return;
        }
    }

    const ChartSurface& s_;
    std::vector<uint32_t> chartOf_;  ///< per mesh triangle: chart, kFree, or kAbsent (not segmented)
    std::vector<uint32_t> triangles_;
    std::vector<Growing> charts_;
};

}  // namespace

ChartSurface::ChartSurface(const IndexedMesh& m) : mesh(m), topology(buildMeshTopology(m)) {
    const size_t triangles = m.triangleCount();
    normal.assign(triangles, glm::dvec3(0.0));
    area.assign(triangles, 0.0);
    for (size_t t = 0; t < triangles; ++t) {
        const uint32_t* i = &m.indices[3 * t];
        if (topology.weld[i[0]] == topology.weld[i[1]] || topology.weld[i[1]] == topology.weld[i[2]] ||
            topology.weld[i[0]] == topology.weld[i[2]])
            continue;
        const glm::dvec3 p0(m.position[i[0]]), p1(m.position[i[1]]), p2(m.position[i[2]]);
        const glm::dvec3 n = glm::cross(p1 - p0, p2 - p0);
        const double length = glm::length(n);
        if (!(length > 0) || !std::isfinite(length)) continue;
        normal[t] = n / length;
        area[t] = 0.5 * length;
    }
}

std::vector<std::vector<uint32_t>> segmentCharts(const ChartSurface& surface, std::span<const uint32_t> triangles,
                                                 double coneDeg, double smallArea) {
    Segmenter segmenter(surface, triangles);
    segmenter.grow(cosDeg(coneDeg));
    if (smallArea > 0) segmenter.merge(smallArea, cosDeg(coneDeg + kChartSlackDeg));
    return segmenter.result();
}

glm::dvec3 meanNormal(const ChartSurface& surface, std::span<const uint32_t> triangles) {
    glm::dvec3 sum(0.0);
    for (uint32_t t : triangles) sum += surface.area[t] * surface.normal[t];
    const double length = glm::length(sum);
    return length > 0 ? sum / length : glm::dvec3(0, 0, 1);
}

}  // namespace penumbra
