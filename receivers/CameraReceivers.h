#pragma once
/// @file CameraReceivers.h
/// @brief Camera receivers: rasterize the scene into a z-buffer, one triangle at a time, and turn
/// every covered pixel into a receiver at the visible surface point.

#include "receivers/ReceiverSet.h"
#include "stream/TriangleSource.h"

#include <glm/vec3.hpp>

#include <array>
#include <functional>
#include <string>

namespace penumbra {

/// @brief A pinhole camera; fov_deg is the vertical field of view.
struct CameraDesc {
    glm::dvec3 eye{0, 3, 8}, target{0.0}, up{0, 1, 0};
    double fovDeg = 45.0;
    int width = 640, height = 480;
    /// Deep option: receivers at the nearest `layers` distinct depths per pixel (1..16). Layer k's
    /// receivers have pixel = k * width * height + y * width + x.
    int layers = 1;
    std::string where = "receivers";

    /// Unit direction of the ray through the centre of pixel (x, y); y grows downwards.
    glm::dvec3 pixelDirection(int x, int y) const;
};

/// @brief Checks the camera; throws InputError naming `where` and the bad value.
void validateCamera(const CameraDesc& camera);

/// @brief The z-buffer pass as an object that is fed chunks, so that it can share a pass over the
/// stream with other work (the area histogram). Holds 16 bytes per pixel until finish().
class CameraRasterizer {
public:
    /// @throw InputError when the camera is invalid (validateCamera()).
    explicit CameraRasterizer(const CameraDesc& camera);
    /// Rasterizes the chunk; triangles are depth-tested in the order given.
    void add(std::span<const Triangle> chunk);
    /// Also keep, per pixel, the vertices of the triangle that wins it (36 more bytes per pixel),
    /// for shading that needs the visible triangle (smooth coherent shading). Call before add().
    void recordTriangles() { triangle_.assign(depth_.size(), {}); }
    /// One receiver per covered pixel and layer: layer 0 in scanline order, then layer 1... Call once.
    ReceiverSet finish();
    /// After finish() with recordTriangles(): each receiver's triangle, in receiver order.
    std::vector<std::array<glm::vec3, 3>> takeTriangles() { return std::move(winners_); }
    /// Bytes per pixel held while rasterizing.
    static constexpr uint64_t kBytesPerPixel = 16;

private:
    glm::dvec3 direction(int x, int y) const;
    CameraDesc camera_;
    glm::dvec3 right_, up_, forward_;
    double tanHalf_, aspect_;
    std::vector<float> depth_;
    std::vector<glm::vec3> normal_;
    std::vector<std::array<glm::vec3, 3>> triangle_, winners_;
};

/// @brief Rasterizes every triangle of @p source (one pass, streamed) and returns one receiver per
/// covered pixel, in scanline order, at the nearest surface along the pixel's centre ray. The
/// normal is the geometric normal of the visible triangle, turned to face the camera.
/// Depth ties keep the earlier triangle, so the result depends only on the stream order.
/// @param onChunk called with the triangles of each chunk after rasterizing it (lets the caller
/// build an area histogram in the same pass).
ReceiverSet rasterizeCamera(TriangleSource& source, const CameraDesc& camera,
                            const std::function<void(std::span<const Triangle>)>& onChunk = {});

}  // namespace penumbra
