#include "receivers/CameraReceivers.h"
#include "stream/util/Memory.h"
#include "receivers/PolygonSpan.h"

#include "stream/util/Error.h"
#include "stream/util/BandLists.h"
#include "stream/util/TexelIndex.h"

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace penumbra {

CameraBasis cameraBasis(const CameraDesc& c) {
    CameraBasis b;
    b.forward = glm::normalize(c.target - c.eye);
    b.right = glm::normalize(glm::cross(b.forward, c.up));
    b.up = glm::cross(b.right, b.forward);
    b.tanHalf = std::tan(glm::radians(c.fovDeg) * 0.5);
    b.aspect = double(c.width) / c.height;
    return b;
}

namespace {

/// The image-plane offsets of the centres of column x and row y of a w x h image.
double columnOffset(const CameraBasis& b, int w, int x) { return (2.0 * (x + 0.5) / w - 1.0) * b.tanHalf * b.aspect; }
double rowOffset(const CameraBasis& b, int h, int y) { return (1.0 - 2.0 * (y + 0.5) / h) * b.tanHalf; }

/// Unit direction of the ray through the centre of pixel (x, y) of a w x h image.
glm::dvec3 directionThrough(const CameraBasis& b, int w, int h, int x, int y) {
    return glm::normalize(b.forward + columnOffset(b, w, x) * b.right + rowOffset(b, h, y) * b.up);
}

/// Row bands of the image drawn in parallel by CameraRasterizer::add(): eight per thread, so
/// that the cores stay busy where the triangles crowd into part of the image, and one on one
/// thread (each band boundary a triangle crosses costs a second visit). Any count gives the
/// same pixels: each band tests its triangles in chunk order.
int rowBands() {
    // --threads limits TBB through a global_control, which the arena's concurrency does not show.
    const int threads = std::min<int>(tbb::this_task_arena::max_concurrency(),
                                      int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)));
    return threads <= 1 ? 1 : std::min(64, 8 * threads);
}

}  // namespace

glm::dvec3 CameraDesc::pixelDirection(int x, int y) const { return directionThrough(cameraBasis(*this), width, height, x, y); }

void validateCamera(const CameraDesc& c) {
    if (c.width < 1 || c.height < 1 || c.width > 65536 || c.height > 65536)
        fail(c.where, "width and height must be in 1..65536, got {}x{}", c.width, c.height);
    if (!(c.fovDeg > 0.0 && c.fovDeg < 180.0)) fail(c.where.empty() ? std::string("fov_deg") : c.where + ".fov_deg", "must be in (0, 180), got {}", c.fovDeg);
    glm::dvec3 f = c.target - c.eye;
    if (!(glm::length(f) > 0.0)) fail(c.where, "eye and target are the same point");
    if (c.layers < 1 || c.layers > 16) fail(c.where, "layers must be in 1..16, got {}", c.layers);
    if (uint64_t(c.width) * c.height * c.layers >= (1ull << 32))
        fail(c.where, "width x height x layers must be below 2^32, got {}x{}x{}", c.width, c.height, c.layers);
    if (!(glm::length(glm::cross(f, c.up)) > 1e-12 * glm::length(f) * glm::length(c.up)))
        fail(c.where, "up is parallel to the view direction (or zero)");
}

CameraRasterizer::CameraRasterizer(const CameraDesc& camera) : camera_(camera) {
    validateCamera(camera);
    CameraBasis b = cameraBasis(camera);
    right_ = b.right, up_ = b.up, forward_ = b.forward, tanHalf_ = b.tanHalf, aspect_ = b.aspect;
    tabulateRays();
    const size_t pixels = size_t(camera.width) * camera.height * camera.layers;
    depth_.assign(pixels, std::numeric_limits<float>::infinity());
    normal_.assign(pixels, glm::vec3(0.0f));
}

CameraRasterizer::CameraRasterizer(const CameraDesc& camera, int subdivision, std::span<const uint32_t> pixels)
    : camera_(camera), sub_(subdivision), coarseWidth_(camera.width), refined_(pixels.begin(), pixels.end()) {
    validateCamera(camera);
    if (subdivision < 1 || camera.layers != 1) fail(camera.where, "refinement needs a subdivision >= 1 and one layer");
    camera_.width *= subdivision, camera_.height *= subdivision;
    CameraBasis b = cameraBasis(camera_);
    right_ = b.right, up_ = b.up, forward_ = b.forward, tanHalf_ = b.tanHalf, aspect_ = b.aspect;
    tabulateRays();
    lookup_.assign(size_t(camera.width) * camera.height, ~0u);
    for (size_t i = 0; i < refined_.size(); ++i) lookup_[refined_[i]] = uint32_t(i);
    const size_t slots = refined_.size() * size_t(sub_) * sub_;
    depth_.assign(slots, std::numeric_limits<float>::infinity());
    normal_.assign(slots, glm::vec3(0.0f));
}

size_t CameraRasterizer::slotOf(int x, int y) const {
    if (sub_ == 1) return (size_t(y) * camera_.width + x) * size_t(camera_.layers);
    const uint32_t i = lookup_[size_t(y / sub_) * coarseWidth_ + x / sub_];
    if (i == ~0u) return SIZE_MAX;
    return (size_t(i) * sub_ + y % sub_) * sub_ + x % sub_;
}

void CameraRasterizer::tabulateRays() {
    const CameraBasis b{right_, up_, forward_, tanHalf_, aspect_};
    columnRay_.resize(size_t(camera_.width)), rowOffset_.resize(size_t(camera_.height));
    for (int x = 0; x < camera_.width; ++x) columnRay_[size_t(x)] = b.forward + columnOffset(b, camera_.width, x) * b.right;
    for (int y = 0; y < camera_.height; ++y) rowOffset_[size_t(y)] = rowOffset(b, camera_.height, y);
}

glm::dvec3 CameraRasterizer::direction(int x, int y) const {
    // The same sums in the same order as directionThrough(), so the same bits.
    return glm::normalize(columnRay_[size_t(x)] + rowOffset_[size_t(y)] * up_);
}

bool CameraRasterizer::opaqueAlong(const Triangle& tri, const glm::dvec3& d) const {
    const uint32_t id = alphaIdOf(tri.flags);
    if (!alpha_ || id == 0) return true;
    return alpha_->lookupAlong(id, tri.v[0], tri.v[1], tri.v[2], camera_.eye, d).opaque;
}

/// One triangle of a chunk, set up for drawing: its near-clipped polygon on the image (m
/// vertices), its plane, and the pixel box it can cover (y0 > y1: none).
struct CameraRasterizer::Projected {
    double sx[4], sy[4];
    glm::dvec3 n;
    /// normalize(n) as a float vector: normalize(-n) is its negation exactly (the same scale).
    glm::vec3 unitNormal{0.0f};
    double planeD = 0, orient = 1;
    /// No depth this triangle writes is below it (0: no bound), so a pixel whose kept depths are
    /// all at most this cannot take it (depthFloorOf()).
    float depthFloor = 0;
    int m = 0, x0 = 0, x1 = -1, y0 = 0, y1 = -1;
    bool spans = false;
};

namespace {

/// A float at most every depth drawRows() can compute for triangle @p v seen from @p eye, with
/// @p n its (unnormalised) normal and @p planeD = n . (v0 - eye); 0 when there is none worth having.
///
/// A pixel's depth is t = planeD / (n . d), d the pixel's unit ray, and in real arithmetic, for
/// a ray through the triangle, t is the distance to a point of it, so at least `near`, the
/// distance from the eye to the triangle's box. The computed t differs from that by far less
/// than a millionth while n . d is not tiny: |n . d| = |planeD| / t >= |planeD| / far, with far
/// the farthest vertex, and a triangle seen within 1e-3 of edge-on gets no bound. (The pixel
/// test also admits rays a rounding error outside the triangle: a relative displacement of a
/// few ulps over that cosine, again far below a millionth.) So near (1 - 1e-6), rounded to
/// float (a relative 6e-8), is below every computed t, and float(t) cannot be below it.
float depthFloorOf(const glm::dvec3 (&v)[3], const glm::dvec3& eye, const glm::dvec3& n, double planeD) {
    const glm::dvec3 lo = glm::min(glm::min(v[0], v[1]), v[2]), hi = glm::max(glm::max(v[0], v[1]), v[2]);
    const double near = glm::length(glm::max(lo - eye, 0.0) + glm::max(eye - hi, 0.0));
    const double far = std::max({glm::length(v[0] - eye), glm::length(v[1] - eye), glm::length(v[2] - eye)});
    if (!(std::abs(planeD) >= 1e-3 * glm::length(n) * far) || !(near > 0)) return 0.0f;
    return float(near * (1.0 - 1e-6));
}

}  // namespace

struct CameraRasterizer::Scratch {
    std::vector<Projected> projected;
    BandLists bands;
};

void CameraRasterizer::ScratchDeleter::operator()(Scratch* s) const { delete s; }

[[gnu::always_inline]] inline void CameraRasterizer::project(const Triangle& tri, Projected& q) const {
    const int W = camera_.width, H = camera_.height;
    const double nearZ = 1e-6;
    q.y0 = 0, q.y1 = -1;
    glm::dvec3 v[3] = {glm::dvec3(tri.v[0]), glm::dvec3(tri.v[1]), glm::dvec3(tri.v[2])};
    q.n = glm::cross(v[1] - v[0], v[2] - v[0]);
    if (!(glm::length(q.n) > 0.0) || !std::isfinite(glm::length(q.n))) return;
    // Camera space, then clip against the near plane (at most 4 vertices remain).
    glm::dvec3 c[3];
    for (int i = 0; i < 3; ++i) {
        glm::dvec3 d = v[i] - camera_.eye;
        c[i] = {glm::dot(d, right_), glm::dot(d, up_), glm::dot(d, forward_)};
    }
    glm::dvec3 poly[4];
    int m = 0;
    for (int i = 0; i < 3; ++i) {
        const glm::dvec3 &p = c[i], &r = c[(i + 1) % 3];
        if (p.z >= nearZ) poly[m++] = p;
        if ((p.z >= nearZ) != (r.z >= nearZ)) poly[m++] = p + (r - p) * ((nearZ - p.z) / (r.z - p.z));
    }
    if (m < 3) return;
    double xLo = INFINITY, xHi = -INFINITY, yLo = INFINITY, yHi = -INFINITY;
    for (int i = 0; i < m; ++i) {
        q.sx[i] = (poly[i].x / poly[i].z / (tanHalf_ * aspect_) + 1.0) * 0.5 * W;
        q.sy[i] = (1.0 - poly[i].y / poly[i].z / tanHalf_) * 0.5 * H;
        xLo = std::min(xLo, q.sx[i]), xHi = std::max(xHi, q.sx[i]);
        yLo = std::min(yLo, q.sy[i]), yHi = std::max(yHi, q.sy[i]);
    }
    q.m = m;
    // Clamped before the conversion: a polygon clipped at the near plane can reach billions of
    // pixels, and int() of those is undefined (x86 gives INT_MIN, which dropped a triangle that
    // reaches far to the right or below).
    q.x0 = clampedTexel(std::ceil(xLo - 0.5), 0, W), q.x1 = clampedTexel(std::floor(xHi - 0.5), -1, W - 1);
    const int y0 = clampedTexel(std::ceil(yLo - 0.5), 0, H), y1 = clampedTexel(std::floor(yHi - 0.5), -1, H - 1);
    if (q.x0 > q.x1 || y0 > y1) return;
    double area = 0;
    for (int i = 0; i < m; ++i) area += q.sx[i] * q.sy[nextCorner(i, m)] - q.sx[nextCorner(i, m)] * q.sy[i];
    if (area == 0) return;
    q.orient = area > 0 ? 1.0 : -1.0;
    q.planeD = glm::dot(q.n, v[0] - camera_.eye);
    q.depthFloor = depthFloorOf(v, camera_.eye, q.n, q.planeD);
    q.unitNormal = glm::vec3(glm::normalize(q.n));
    q.spans = std::max({std::abs(xLo), std::abs(xHi), std::abs(yLo), std::abs(yHi)}) < 1e9;
    q.y0 = y0, q.y1 = y1;
}

[[gnu::always_inline]] inline void CameraRasterizer::drawRows(const Triangle& tri, const Projected& setup, size_t index, int yLo, int yHi) {
    // A local copy: the stores to the pixels below (class_ is bytes, which may alias anything)
    // would otherwise make the compiler reload the setup for every pixel.
    const Projected q = setup;
    const double *sx = q.sx, *sy = q.sy;
    const int m = q.m;
    const int yFirst = std::max(yLo, q.y0), yLast = std::min(yHi, q.y1);
    PolygonSpans spans;
    if (q.spans) setUpSpans(sx, sy, m, q.orient, yFirst + 0.5, yLast + 0.5, std::max(std::abs(q.x0 + 0.5), std::abs(q.x1 + 0.5)), spans);
    for (int y = yFirst; y <= yLast; ++y) {
        double py = y + 0.5;
        int xa = q.x0, xb = q.x1;
        if (q.spans) {  // only the pixels in the polygon's row span get the exact test
            double lo = -INFINITY, hi = INFINITY;
            rowSpan(spans, py, lo, hi);
            if (!(lo <= hi)) continue;
            xa = std::max(q.x0, clampedTexel(std::ceil(lo - 0.5), q.x0, q.x1 + 1));
            xb = std::min(q.x1, clampedTexel(std::floor(hi - 0.5), q.x0 - 1, q.x1));
        }
        const size_t L = size_t(camera_.layers);
        for (int x = xa; x <= xb; ++x) {
            const size_t base = slotOf(x, y);
            if (base == SIZE_MAX) continue;
            // Behind every surface the pixel keeps (most of dense grass' inside tests): the depth
            // test below would refuse it; the ray and its division are not needed to know that.
            if (q.depthFloor >= depth_[base + L - 1]) continue;
            if (!insidePolygon(sx, sy, m, q.orient, x + 0.5, py)) continue;
            glm::dvec3 d = direction(x, y);
            double denom = glm::dot(q.n, d);
            if (denom == 0.0) continue;
            double t = q.planeD / denom;
            if (!(t > 0.0)) continue;
            // Slots of a pixel hold its nearest distinct depths, ascending; a depth equal to
            // one already kept is the same surface again, and the earlier triangle keeps it.
            const float ft = float(t);
            size_t k = 0;
            while (k < L && !(ft < depth_[base + k])) ++k;
            if (k == L || (k > 0 && depth_[base + k - 1] == ft)) continue;
            if (!opaqueAlong(tri, d)) continue;  // a clear texel: the camera sees what is behind
            for (size_t j = L - 1; j > k; --j) {
                depth_[base + j] = depth_[base + j - 1], normal_[base + j] = normal_[base + j - 1];
                if (!triangle_.empty()) triangle_[base + j] = triangle_[base + j - 1];
                if (!triangleId_.empty()) triangleId_[base + j] = triangleId_[base + j - 1];
                if (!class_.empty()) class_[base + j] = class_[base + j - 1];
            }
            depth_[base + k] = ft;
            normal_[base + k] = denom > 0 ? -q.unitNormal : q.unitNormal;
            if (!triangle_.empty()) triangle_[base + k] = {tri.v[0], tri.v[1], tri.v[2]};
            if (!triangleId_.empty()) triangleId_[base + k] = (seen_ + index) | (denom > 0 ? kFlippedBit : 0);
            if (!class_.empty()) class_[base + k] = uint8_t(receiverClassOf(tri.flags));
        }
    }
}

void CameraRasterizer::add(std::span<const Triangle> chunk) {
    const int H = camera_.height, rows = (H + rowBands() - 1) / rowBands(), bands = (H + rows - 1) / rows;
    if (bands == 1) {  // one thread: draw each triangle as it is set up (the setups stay in cache)
        Projected q;
        for (size_t i = 0; i < chunk.size(); ++i) {
            project(chunk[i], q);
            if (q.y0 <= q.y1) drawRows(chunk[i], q, i, 0, H - 1);
        }
        seen_ += chunk.size();
        return;
    }
    // Set up every triangle once, then let bands of rows draw the ones that reach them. A band
    // owns its rows' pixels, and reads its triangles in chunk order (a counting sort by band),
    // so each pixel's depth tests run in stream order, as on one thread.
    // The buffers live as long as the rasterizer: a chunk's setups are half a megabyte, which
    // malloc would map and unmap (and the kernel zero) for every chunk.
    if (!scratch_) scratch_.reset(new Scratch);
    std::vector<Projected>& projected = scratch_->projected;
    projected.resize(chunk.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, chunk.size(), 256), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i < range.end(); ++i) project(chunk[i], projected[i]);
    });
    BandLists& lists = scratch_->bands;
    lists.build(bands, projected.size(), [&](size_t i, int& lo, int& hi) {
        const Projected& q = projected[i];
        lo = q.y0 <= q.y1 ? q.y0 / rows : 0, hi = q.y0 <= q.y1 ? q.y1 / rows : -1;
    });
    const std::vector<uint32_t>&first = lists.first, &members = lists.members;
    tbb::parallel_for(0, bands, [&](int band) {
        const int yLo = band * rows, yHi = std::min(H, yLo + rows) - 1;
        for (uint32_t k = first[size_t(band)]; k < first[size_t(band) + 1]; ++k)
            drawRows(chunk[members[k]], projected[members[k]], members[k], yLo, yHi);
    });
    seen_ += chunk.size();
}

ReceiverSet CameraRasterizer::finish() {
    const int W = camera_.width, H = camera_.height;
    ReceiverSet set;
    set.width = W, set.height = H;
    const size_t L = size_t(camera_.layers);
    // Exact sizes up front: growing four vectors by doubling next to the z-buffer would briefly
    // need two to three times the receiver set, and that, not casting, set the peak RSS of
    // large bakes.
    const size_t covered = size_t(std::count_if(depth_.begin(), depth_.end(), [](float d) { return std::isfinite(d); }));
    set.position.reserve(covered), set.normal.reserve(covered), set.pixel.reserve(covered), set.depth.reserve(covered);
    if (!triangle_.empty()) winners_.reserve(covered);
    if (!triangleId_.empty()) winnerIds_.reserve(covered);
    if (!class_.empty()) winnerClasses_.reserve(covered);
    auto emit = [&](size_t slot, int x, int y, uint32_t pixel) {
        set.position.push_back(glm::vec3(camera_.eye + double(depth_[slot]) * direction(x, y)));
        set.normal.push_back(normal_[slot]);
        set.pixel.push_back(pixel);
        set.depth.push_back(depth_[slot]);
        if (!triangle_.empty()) winners_.push_back(triangle_[slot]);
        if (!triangleId_.empty()) winnerIds_.push_back(triangleId_[slot]);
        if (!class_.empty()) winnerClasses_.push_back(class_[slot]);
    };
    if (sub_ > 1) {  // refinement: pixel by pixel, sub-pixels in scanline order
        set.width = coarseWidth_, set.height = H / sub_;
        for (size_t i = 0, slot = 0; i < refined_.size(); ++i) {
            const int x0 = int(refined_[i] % coarseWidth_) * sub_, y0 = int(refined_[i] / coarseWidth_) * sub_;
            for (int sy = 0; sy < sub_; ++sy)
                for (int sx = 0; sx < sub_; ++sx, ++slot)
                    if (std::isfinite(depth_[slot])) emit(slot, x0 + sx, y0 + sy, refined_[i]);
        }
        releaseStorage(depth_), releaseStorage(normal_), releaseStorage(triangle_), releaseStorage(lookup_), releaseStorage(class_);
        return set;
    }
    for (size_t layer = 0; layer < L; ++layer)
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                size_t p = size_t(y) * W + x, slot = p * L + layer;
                if (std::isfinite(depth_[slot])) emit(slot, x, y, uint32_t(layer * size_t(W) * H + p));
            }
    releaseStorage(depth_), releaseStorage(normal_), releaseStorage(triangle_), releaseStorage(triangleId_), releaseStorage(class_);
    return set;
}

ReceiverSet rasterizeCamera(TriangleSource& source, const CameraDesc& camera,
                            const std::function<void(std::span<const Triangle>)>& onChunk,
                            std::shared_ptr<const AlphaTable> alpha) {
    CameraRasterizer raster(camera);
    raster.seeThroughCutOuts(std::move(alpha));
    std::vector<Triangle> chunk(kTriangleChunk);
    while (size_t count = source.read(chunk)) {
        std::span<const Triangle> part(chunk.data(), count);
        raster.add(part);
        if (onChunk) onChunk(part);
    }
    return raster.finish();
}

}  // namespace penumbra
