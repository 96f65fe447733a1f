#pragma once
/// @file MeshPreview.h
/// @brief A small software rasterizer for the PNG preview of a vertex bake: triangles with
/// per-vertex colours, a z-buffer and perspective-correct interpolation, drawn one at a time in
/// the order given (so the image does not depend on the thread count).

#include "receivers/CameraReceivers.h"

#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace penumbra {

/// @brief The view a vertex bake's preview uses without a camera: a three-quarter view from
/// above (+y up) that frames the box [@p lo, @p hi] with a small margin.
CameraDesc framingCamera(const glm::dvec3& lo, const glm::dvec3& hi, int width = 640, int height = 480);

/// @brief Rasterizes coloured triangles into a z-buffer; 16 bytes per pixel.
class MeshPreviewRaster {
public:
    /// @param camera validated (validateCamera()); its layers are ignored.
    explicit MeshPreviewRaster(const CameraDesc& camera);

    /// @brief Draws one triangle with linear colours per corner. Triangles with a corner at or
    /// behind the camera's near plane are skipped rather than clipped: a preview, not a render.
    void add(const std::array<glm::vec3, 3>& position, const std::array<glm::vec3, 3>& colour);

    /// @brief The image as 8-bit sRGB, RGB interleaved, top row first; pixels nothing covered
    /// hold PreviewTone::kBackground.
    std::vector<uint8_t> rgb() const;

    int width() const { return width_; }
    int height() const { return height_; }
    /// Bytes held for a @p width x @p height preview (z-buffer and colours, then the 8-bit image).
    static uint64_t bytes(int width, int height) { return uint64_t(width) * uint64_t(height) * 19; }

private:
    /// Screen position (x right, y down, in pixels) and view depth of a world point.
    glm::dvec3 project(const glm::vec3& p) const;

    CameraBasis basis_;
    glm::dvec3 eye_;
    int width_, height_;
    double near_;
    std::vector<float> depth_;
    std::vector<glm::vec3> colour_;
};

}  // namespace penumbra
