#include "bake/EmbreeCaster.h"

// How this differs from the blocking rule (BlockingRule.h), and why only on ties:
//
//  - Precision. The rule evaluates in double from float inputs; Embree intersects in float.
//    The ray direction l - r is computed in double and rounded to float, tnear and tfar are
//    floats, and Embree's hit distance carries float roundoff. Decisions therefore differ only
//    where a tested quantity is within roundoff of its threshold.
//  - Edges. The rule includes every edge of every triangle (a segment through a shared edge is
//    blocked by both triangles). Embree's float triangle test is not exactly inclusive: a ray
//    through an edge or vertex, up to roundoff, may hit either, both or neither neighbour.
//  - The receiver-end epsilon. The rule measures eps(r) perpendicular to T's plane; here it is
//    the excluded start of the ray, tnear = eps(r) / |l - r|, i.e. eps(r) measured along the ray.
//    Distance along the ray is never shorter than the perpendicular distance, so every relation
//    the rule blocks through the band test is also beyond tnear; Embree can additionally block
//    when r is within eps(r) of T's plane but the ray reaches T more than eps(r) away from r
//    (grazing rays). Those relations are inside isTie()'s epsilon band. In the tests, this is
//    where nearly all mismatches are: a receiver lying on a triangle, a ray nearly parallel to
//    that triangle, and Embree's float hit distance (roundoff ~1e-7 x coordinates, divided by
//    the cosine between ray and plane) landing beyond tnear, so Embree shadows the receiver
//    with its own triangle where the rule does not.
//  - The light end. The rule never blocks a sample by a triangle whose plane contains it; here
//    the ray stops at tfar = 1 - 1e-6 (relative), so a triangle within that distance of the
//    sample (including one containing it, up to Embree's roundoff) does not block. Both cases
//    have the sample within isTie()'s tolerance of T's plane.
//  - Degenerate relations (l == r, |l - r| <= eps(r), non-finite receivers) are not traced and
//    count as unblocked, which is what the rule gives for them too.
//
// Build quality: RTC_BUILD_QUALITY_HIGH (spatial-split SAH BVH), the setting Embree recommends for
// static, final-frame scenes. A bake builds once and traces receivers x samples rays (typically
// hundreds of rays per triangle), so the slower commit is repaid by faster traversal. The cost is
// a larger BVH (split references); sceneBytes reports only the vertex and index buffers.

#include "bake/BlockingRule.h"
#include "stream/Error.h"

#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#if defined(__SSE__) || defined(_M_X64)
#include <pmmintrin.h>
#include <xmmintrin.h>
#define PENUMBRA_HAVE_MXCSR 1
#endif

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <string>

namespace penumbra {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

const char* errorName(RTCError code) {
    switch (code) {
        case RTC_ERROR_NONE: return "RTC_ERROR_NONE";
        case RTC_ERROR_UNKNOWN: return "RTC_ERROR_UNKNOWN";
        case RTC_ERROR_INVALID_ARGUMENT: return "RTC_ERROR_INVALID_ARGUMENT";
        case RTC_ERROR_INVALID_OPERATION: return "RTC_ERROR_INVALID_OPERATION";
        case RTC_ERROR_OUT_OF_MEMORY: return "RTC_ERROR_OUT_OF_MEMORY";
        case RTC_ERROR_UNSUPPORTED_CPU: return "RTC_ERROR_UNSUPPORTED_CPU";
        case RTC_ERROR_CANCELLED: return "RTC_ERROR_CANCELLED";
    }
    return "RTC_ERROR_(unrecognised)";
}

/// First error reported through the device's error function, from any thread. Embree calls the
/// function from inside C code (possibly on worker threads), so it must not throw: errors are
/// recorded here and turned into InputError at the next check().
struct ErrorState {
    std::mutex mutex;
    RTCError code = RTC_ERROR_NONE;
    std::string message;

    static void callback(void* user, RTCError code, const char* str) {
        auto* self = static_cast<ErrorState*>(user);
        std::lock_guard lock(self->mutex);
        if (self->code != RTC_ERROR_NONE) return;  // keep the first one
        self->code = code;
        self->message = str ? str : "";
    }

    /// Throws if the callback recorded an error or the calling thread's error code is set.
    void check(RTCDevice device, const char* stage) {
        RTCError code = rtcGetDeviceError(device);  // also clears this thread's code
        std::string message;
        {
            std::lock_guard lock(mutex);
            if (this->code != RTC_ERROR_NONE) code = this->code, message = this->message;
        }
        if (code == RTC_ERROR_NONE) return;
        if (message.empty()) fail("embree", "{} during {}", errorName(code), stage);
        fail("embree", "{} during {}: {}", errorName(code), stage, message);
    }
};

struct DeviceHandle {
    RTCDevice device = nullptr;
    ~DeviceHandle() {
        if (device) rtcReleaseDevice(device);
    }
};

struct SceneHandle {
    RTCScene scene = nullptr;
    ~SceneHandle() {
        if (scene) rtcReleaseScene(scene);
    }
};

struct GeometryHandle {
    RTCGeometry geometry = nullptr;
    ~GeometryHandle() {
        if (geometry) rtcReleaseGeometry(geometry);
    }
};

/// Flush-to-zero and denormals-are-zero for Embree calls on this thread (Embree's recommendation:
/// denormals slow traversal down badly). The previous MXCSR is restored on exit, so TBB worker
/// threads that later run other (double-precision) work, such as the reference caster, are not
/// affected.
class DenormalsOff {
public:
#ifdef PENUMBRA_HAVE_MXCSR
    DenormalsOff() : saved_(_mm_getcsr()) {
        _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
        _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
    }
    ~DenormalsOff() { _mm_setcsr(saved_); }

private:
    unsigned int saved_;
#endif
};

constexpr int kPacket = 16;
/// Rays end just before the light sample (in units of l - r), so the sample itself is excluded.
constexpr float kTfar = 1.0f - 1e-6f;

/// The triangles Embree gets: finite, with non-zero area (the rule's BlockerTriangle::valid).
std::vector<const Triangle*> validTriangles(std::span<const Triangle> triangles) {
    std::vector<const Triangle*> kept;
    kept.reserve(triangles.size());
    for (const Triangle& t : triangles)
        if (isFinite(t) && BlockerTriangle::from(t).valid) kept.push_back(&t);
    if (kept.size() > size_t(std::numeric_limits<uint32_t>::max()) / 3)
        fail("embree", "{} triangles exceed the 32-bit vertex index range of one Embree geometry", kept.size());
    return kept;
}

/// Copies @p kept (non-empty) into Embree-allocated buffers, which carry the padding Embree needs
/// for vector loads of the last vertex. Vertices are not shared: three per triangle.
void fillBuffers(RTCGeometry geometry, const std::vector<const Triangle*>& kept) {
    const size_t n = kept.size();
    auto* vertices = static_cast<float*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * n));
    auto* indices = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), n));
    if (!vertices || !indices) return;  // the error function has the reason
    for (size_t i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c) {
            const glm::vec3& v = kept[i]->v[c];
            vertices[9 * i + 3 * c + 0] = v.x;
            vertices[9 * i + 3 * c + 1] = v.y;
            vertices[9 * i + 3 * c + 2] = v.z;
            indices[3 * i + c] = uint32_t(3 * i + c);
        }
    }
}

/// One packet being filled: lane i answers bit laneBit[i] of word laneWord[i] of the receiver row.
struct Packet {
    RTCRay16 ray;  // RTC_ALIGN(64)
    alignas(64) int valid[kPacket];
    int laneWord[kPacket];
    int laneBit[kPacket];
    int lanes = 0;

    Packet() { reset(); }
    void reset() {
        lanes = 0;
        for (int i = 0; i < kPacket; ++i) {
            valid[i] = 0;
            ray.org_x[i] = ray.org_y[i] = ray.org_z[i] = 0.0f;
            ray.dir_x[i] = ray.dir_y[i] = 0.0f;
            ray.dir_z[i] = 1.0f;
            ray.tnear[i] = 0.0f;
            ray.tfar[i] = 0.0f;
            ray.time[i] = 0.0f;
            ray.mask[i] = ~0u;
            ray.id[i] = unsigned(i);
            ray.flags[i] = 0;
        }
    }
};

}  // namespace

VisibilityMasks castEmbree(const LightSamples& samples, const ReceiverSet& receivers,
                           std::span<const uint32_t> sampleSetOf, std::span<const Triangle> triangles,
                           double epsilon, EmbreeStats* stats, const std::function<void(uint64_t)>& progress) {
    EmbreeStats local;
    const auto buildStart = Clock::now();
    DenormalsOff denormals;  // the calling thread takes part in the build and in parallel_for

    // Declaration order matters: the error state outlives the device, the device outlives the
    // scene and geometry (destructors run in reverse order on every path, including throws).
    ErrorState errors;
    DeviceHandle device;
    device.device = rtcNewDevice(nullptr);
    if (!device.device) {
        RTCError code = rtcGetDeviceError(nullptr);
        fail("embree", "{} creating the device", errorName(code));
    }
    rtcSetDeviceErrorFunction(device.device, &ErrorState::callback, &errors);
    errors.check(device.device, "device creation");
    // A shadow ray must be blocked from both sides of a triangle.
    if (rtcGetDeviceProperty(device.device, RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED))
        fail("embree", "this Embree library was built with backface culling, which shadow rays cannot use");

    SceneHandle scene;
    scene.scene = rtcNewScene(device.device);
    errors.check(device.device, "scene creation");
    rtcSetSceneFlags(scene.scene, RTC_SCENE_FLAG_NONE);
    rtcSetSceneBuildQuality(scene.scene, RTC_BUILD_QUALITY_HIGH);

    {
        const std::vector<const Triangle*> kept = validTriangles(triangles);  // freed before tracing
        local.sceneBytes = uint64_t(kept.size()) * (9 * sizeof(float) + 3 * sizeof(uint32_t));
        if (!kept.empty()) {  // an empty scene needs no geometry (and Embree gets no zero-sized buffers)
            GeometryHandle geometry;
            geometry.geometry = rtcNewGeometry(device.device, RTC_GEOMETRY_TYPE_TRIANGLE);
            errors.check(device.device, "geometry creation");
            rtcSetGeometryBuildQuality(geometry.geometry, RTC_BUILD_QUALITY_HIGH);
            fillBuffers(geometry.geometry, kept);
            errors.check(device.device, "buffer allocation");
            rtcCommitGeometry(geometry.geometry);
            rtcAttachGeometry(scene.scene, geometry.geometry);  // the scene holds its own reference
            errors.check(device.device, "geometry commit");
        }
    }
    rtcCommitScene(scene.scene);
    errors.check(device.device, "BVH build");
    local.buildSeconds = secondsSince(buildStart);

    const auto traceStart = Clock::now();
    VisibilityMasks masks(receivers.size(), samples.groupCount());
    std::atomic<uint64_t> rays{0};
    RTCScene rtcScene = scene.scene;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, receivers.size(), 16), [&](const tbb::blocked_range<size_t>& range) {
        DenormalsOff threadDenormals;
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;  // one receiver's rays share their origin
        Packet packet;
        uint64_t traced = 0;

        for (size_t r = range.begin(); r != range.end(); ++r) {
            uint64_t* row = masks.row(r);
            const glm::vec3 p = receivers.position[r];
            const glm::dvec3 pd(p);
            if (!std::isfinite(pd.x) || !std::isfinite(pd.y) || !std::isfinite(pd.z)) continue;
            const double eps = receiverEpsilon(pd, epsilon);
            const int set = int(sampleSetOf[r]);

            auto flush = [&] {
                if (packet.lanes == 0) return;
                rtcOccluded16(packet.valid, rtcScene, &context, &packet.ray);
                for (int i = 0; i < packet.lanes; ++i)
                    if (packet.valid[i] && packet.ray.tfar[i] == -std::numeric_limits<float>::infinity())
                        row[packet.laneWord[i]] |= 1ull << packet.laneBit[i];
                packet.reset();
            };

            for (int k = 0; k < samples.groupCount(); ++k) {
                const LightSampleGroup& g = samples.groups[k];
                for (uint32_t j = 0; j < g.count; ++j) {
                    const glm::dvec3 l(samples.position(set, int(g.first + j)));
                    const glm::dvec3 d = l - pd;
                    const double len = glm::length(d);
                    // |l - r| <= eps(r): no point of the segment is beyond the receiver band.
                    if (!(len > eps) || !std::isfinite(len)) continue;
                    const float tnear = float(eps / len);
                    if (!(tnear < kTfar)) continue;
                    const int i = packet.lanes++;
                    packet.valid[i] = -1;
                    packet.laneWord[i] = k;
                    packet.laneBit[i] = int(j);
                    packet.ray.org_x[i] = p.x;
                    packet.ray.org_y[i] = p.y;
                    packet.ray.org_z[i] = p.z;
                    packet.ray.dir_x[i] = float(d.x);
                    packet.ray.dir_y[i] = float(d.y);
                    packet.ray.dir_z[i] = float(d.z);
                    packet.ray.tnear[i] = tnear;
                    packet.ray.tfar[i] = kTfar;
                    ++traced;
                    if (packet.lanes == kPacket) flush();
                }
            }
            flush();  // packets never span receivers: the row being written belongs to r
        }
        rays.fetch_add(traced, std::memory_order_relaxed);
        if (progress) progress(range.size());
    });
    errors.check(device.device, "tracing");
    local.traceSeconds = secondsSince(traceStart);
    local.rays = rays.load();
    if (stats) *stats = local;
    return masks;
}

}  // namespace penumbra
