#include "bake/output/MeshPreview.h"

#include "bake/output/ImageWriters.h"
#include "bake/output/PreviewTone.h"

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace penumbra {

CameraDesc framingCamera(const glm::dvec3& lo, const glm::dvec3& hi, int width, int height) {
    CameraDesc c;
    c.width = width, c.height = height, c.fovDeg = 40.0;
    c.target = 0.5 * (lo + hi);
    // The bounding sphere just fits the narrower field of view: the box inside it leaves a margin.
    const double radius = std::max(0.5 * glm::length(hi - lo), 1e-6 * std::max(1.0, glm::length(c.target)));
    const double halfFov = std::atan(std::tan(glm::radians(c.fovDeg) * 0.5) * std::min(1.0, double(width) / height));
    const double distance = radius / std::sin(halfFov);
    // From the front right and above, looking down about 30 degrees: the shading and the shape
    // of the shadows both show.
    c.eye = c.target + distance * glm::normalize(glm::dvec3(0.6, 0.6, 0.8));
    c.where = "receivers.camera";
    return c;
}

MeshPreviewRaster::MeshPreviewRaster(const CameraDesc& camera)
    : basis_(cameraBasis(camera)), eye_(camera.eye), width_(camera.width), height_(camera.height),
      near_(1e-6 * glm::length(camera.target - camera.eye)),
      depth_(size_t(width_) * size_t(height_), std::numeric_limits<float>::infinity()),
      colour_(size_t(width_) * size_t(height_), glm::vec3(PreviewTone::kBackground)) {}

glm::dvec3 MeshPreviewRaster::project(const glm::vec3& p) const {
    const glm::dvec3 d = glm::dvec3(p) - eye_;
    const double z = glm::dot(d, basis_.forward);
    // The inverse of the camera's pixel rays (CameraDesc::pixelDirection): pixel centres at +0.5.
    const double sx = glm::dot(d, basis_.right) / (z * basis_.tanHalf * basis_.aspect);
    const double sy = glm::dot(d, basis_.up) / (z * basis_.tanHalf);
    return {0.5 * (sx + 1.0) * width_, 0.5 * (1.0 - sy) * height_, z};
}

void MeshPreviewRaster::add(const std::array<glm::vec3, 3>& position, const std::array<glm::vec3, 3>& colour) {
    std::array<glm::dvec3, 3> s;
    for (int k = 0; k < 3; ++k) {
        s[size_t(k)] = project(position[size_t(k)]);
        if (!(s[size_t(k)].z > near_) || !std::isfinite(s[size_t(k)].x) || !std::isfinite(s[size_t(k)].y)) return;
    }
    const auto edge = [](const glm::dvec3& a, const glm::dvec3& b, double x, double y) {
        return (b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x);
    };
    const double area = edge(s[0], s[1], s[2].x, s[2].y);
    if (!(std::abs(area) > 0)) return;
    const double x0 = std::max(0.0, std::floor(std::min({s[0].x, s[1].x, s[2].x})));
    const double x1 = std::min(double(width_ - 1), std::ceil(std::max({s[0].x, s[1].x, s[2].x})));
    const double y0 = std::max(0.0, std::floor(std::min({s[0].y, s[1].y, s[2].y})));
    const double y1 = std::min(double(height_ - 1), std::ceil(std::max({s[0].y, s[1].y, s[2].y})));
    for (int y = int(y0); y <= int(y1) && y0 <= y1; ++y)
        for (int x = int(x0); x <= int(x1) && x0 <= x1; ++x) {
            const double px = x + 0.5, py = y + 0.5;
            // Barycentrics in screen space, either winding (previews are two-sided).
            const double w0 = edge(s[1], s[2], px, py) / area, w1 = edge(s[2], s[0], px, py) / area, w2 = 1.0 - w0 - w1;
            if (w0 < 0 || w1 < 0 || w2 < 0) continue;
            // Perspective-correct: 1/z and colour/z are linear on the screen.
            const double q0 = w0 / s[0].z, q1 = w1 / s[1].z, q2 = w2 / s[2].z, inv = q0 + q1 + q2;
            const float z = float(1.0 / inv);
            const size_t at = size_t(y) * size_t(width_) + size_t(x);
            if (!(z < depth_[at])) continue;  // the first triangle drawn wins a tie
            depth_[at] = z;
            colour_[at] = glm::vec3((q0 * glm::dvec3(colour[0]) + q1 * glm::dvec3(colour[1]) + q2 * glm::dvec3(colour[2])) / inv);
        }
}

std::vector<uint8_t> MeshPreviewRaster::rgb() const {
    std::vector<uint8_t> out(colour_.size() * 3);
    for (size_t i = 0; i < colour_.size(); ++i)
        for (int k = 0; k < 3; ++k) out[3 * i + size_t(k)] = encodeSrgb(colour_[i][k]);
    return out;
}

}  // namespace penumbra
