#pragma once
/// @file CameraReceivers.h
/// @brief Camera receivers: rasterize the scene into a z-buffer, one triangle at a time, and turn
/// every covered pixel into a receiver at the visible surface point.

#include "receivers/ReceiverSet.h"
#include "stream/AlphaTable.h"
#include "stream/TriangleSource.h"

#include <glm/vec3.hpp>

#include <array>
#include <functional>
#include <memory>
#include <span>
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

/// @brief The camera's frame: unit right, up and forward (right = forward x up, up = right x
/// forward), tan(fov_deg / 2) and the aspect ratio width / height.
struct CameraBasis {
    glm::dvec3 right, up, forward;
    double tanHalf, aspect;
};
CameraBasis cameraBasis(const CameraDesc& camera);

/// @brief Checks the camera; throws InputError naming `where` and the bad value.
void validateCamera(const CameraDesc& camera);

/// @brief The z-buffer pass as an object that is fed chunks, so that it can share a pass over the
/// stream with other work (the area histogram). Holds 16 bytes per pixel until finish().
///
/// Refinement mode (adaptive antialiasing) rasterizes only the sub-pixels of chosen pixels: an
/// n x n stratified pattern per pixel, at exactly the pixel centres of the same camera at n times
/// the resolution, so a refined pixel's receivers are those of an n-times-larger image.
class CameraRasterizer {
public:
    /// @throw InputError when the camera is invalid (validateCamera()).
    explicit CameraRasterizer(const CameraDesc& camera);
    /// Refinement mode: @p pixels (ascending, layer-0 pixel indices y * width + x) get n x n
    /// sub-pixel slots each, n = @p subdivision. Holds 16 bytes per sub-pixel and 4 per pixel.
    CameraRasterizer(const CameraDesc& camera, int subdivision, std::span<const uint32_t> pixels);
    /// Rasterizes the chunk; triangles are depth-tested in the order given. Bands of rows run in
    /// parallel, each visiting the chunk's triangles in order, so every pixel sees the same
    /// sequence of tests and the result does not depend on the thread count.
    void add(std::span<const Triangle> chunk);
    /// The camera sees through cut-outs: a fragment of a triangle with an alpha id is kept only
    /// where @p table's test (AlphaTable::lookup()) at the pixel ray's hit is opaque, exactly as
    /// a shadow segment through that point would be blocked. The hit's barycentrics come from
    /// the ray's signed volumes with the triangle's edges (as bake/rule/AlphaRule.h does for
    /// segments). Without a table (null), alpha ids are ignored. Call before add().
    void seeThroughCutOuts(std::shared_ptr<const AlphaTable> table) { alpha_ = std::move(table); }
    /// Also keep, per pixel, the vertices of the triangle that wins it (36 more bytes per pixel),
    /// for shading that needs the visible triangle (smooth coherent shading). Call before add().
    void recordTriangles() { triangle_.assign(depth_.size(), {}); }
    /// Cheaper alternative: keep, per pixel, only the winning triangle's position in the order
    /// add() saw it (8 more bytes per pixel; the top bit is set when the triangle's winding faces
    /// away from the camera), so its vertices can be found again in a later pass.
    void recordTriangleIds() { triangleId_.assign(depth_.size(), kNoTriangle); }
    /// Also keep, per pixel, the winning triangle's receiver class (Triangle.h, receiverClassOf():
    /// its entry's "receive_shadows" and "receiver_offset"; 1 more byte per pixel).
    void recordClasses() { class_.assign(depth_.size(), 0); }
    /// One receiver per covered pixel and layer: layer 0 in scanline order, then layer 1... Call once.
    /// In refinement mode: the covered sub-pixels of each chosen pixel, pixel by pixel, each
    /// pixel's sub-pixels in scanline order; `pixel` is the (coarse) pixel they refine.
    ReceiverSet finish();
    /// After finish() with recordTriangles(): each receiver's triangle, in receiver order.
    std::vector<std::array<glm::vec3, 3>> takeTriangles() { return std::move(winners_); }
    /// After finish() with recordTriangleIds(): each receiver's triangle id, in receiver order.
    std::vector<uint64_t> takeTriangleIds() { return std::move(winnerIds_); }
    /// After finish() with recordClasses(): each receiver's receiver class, in receiver order.
    std::vector<uint8_t> takeClasses() { return std::move(winnerClasses_); }
    static constexpr uint64_t kFlippedBit = 1ull << 63, kNoTriangle = ~0ull;
    /// Bytes per pixel held while rasterizing.
    static constexpr uint64_t kBytesPerPixel = 16;

private:
    struct Projected;
    struct Scratch;
    /// Frees the per-chunk buffers of add() (defined where Scratch is complete).
    struct ScratchDeleter {
        void operator()(Scratch* s) const;
    };
    /// Camera space, near-plane clip and image projection of @p tri (thread-safe: reads only).
    void project(const Triangle& tri, Projected& out) const;
    /// Depth-tests @p tri's pixels on rows [@p yLo, @p yHi]; @p index is its place in the chunk.
    void drawRows(const Triangle& tri, const Projected& q, size_t index, int yLo, int yHi);
    glm::dvec3 direction(int x, int y) const;
    /// Fills columnRay_ and rowOffset_ from the basis and the (fine) image size.
    void tabulateRays();
    /// False when the pixel ray along @p d hits a clear texel of @p tri's cut-out.
    bool opaqueAlong(const Triangle& tri, const glm::dvec3& d) const;
    /// Storage slot of (fine) pixel (x, y) and layer 0, or SIZE_MAX when it is not rasterized.
    size_t slotOf(int x, int y) const;
    CameraDesc camera_;
    int sub_ = 1;                     ///< refinement: sub-pixels per pixel side; 1 otherwise
    int coarseWidth_ = 0;
    std::vector<uint32_t> refined_;   ///< refinement: the chosen pixels
    std::vector<uint32_t> lookup_;    ///< refinement: coarse pixel -> index in refined_, or ~0u
    uint64_t seen_ = 0;               ///< triangles given to add() so far
    std::vector<uint64_t> triangleId_, winnerIds_;
    std::vector<uint8_t> class_, winnerClasses_;
    glm::dvec3 right_, up_, forward_;
    double tanHalf_, aspect_;
    std::vector<glm::dvec3> columnRay_;  ///< per column: forward + its offset along right
    std::vector<double> rowOffset_;      ///< per row: its offset along up
    std::vector<float> depth_;
    std::vector<glm::vec3> normal_;
    std::vector<std::array<glm::vec3, 3>> triangle_, winners_;
    std::shared_ptr<const AlphaTable> alpha_;  ///< seeThroughCutOuts(); null: alpha is ignored
    std::unique_ptr<Scratch, ScratchDeleter> scratch_;  ///< add()'s buffers, kept between chunks
};

/// @brief Rasterizes every triangle of @p source (one pass, streamed) and returns one receiver per
/// covered pixel, in scanline order, at the nearest surface along the pixel's centre ray. The
/// normal is the geometric normal of the visible triangle, turned to face the camera.
/// Depth ties keep the earlier triangle, so the result depends only on the stream order.
/// @param onChunk called with the triangles of each chunk after rasterizing it (lets the caller
/// build an area histogram in the same pass).
/// @param alpha when not null, the camera sees through cut-outs (CameraRasterizer::seeThroughCutOuts()).
ReceiverSet rasterizeCamera(TriangleSource& source, const CameraDesc& camera,
                            const std::function<void(std::span<const Triangle>)>& onChunk = {},
                            std::shared_ptr<const AlphaTable> alpha = nullptr);

}  // namespace penumbra
