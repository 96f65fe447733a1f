#include "bake/peers/EmbreeCaster.h"

#include "stream/util/Timer.h"

// How this relates to the blocking rule (BlockingRule.h):
//
//  - Candidates. Embree intersects in float, with its own edge rules; its hits are only
//    candidates. An occlusion filter function evaluates the rule in double for the relation and
//    the candidate triangle, from the same float inputs as hpc (the receiver, the sample, the
//    triangle's vertices), and rejects the hit when the rule does not block. So the receiver
//    epsilon (perpendicular to T's plane), the open light end and sun directions mean exactly
//    what they mean for hpc and reference. A hit far inside the triangle, beyond twice the
//    epsilon band and before the sample by many float ulps is one the rule certainly blocks, and
//    is accepted without the rule (certainlyBlocks()): on GRIDS that is all but a fraction of a
//    percent of the filter's calls. "Far inside" is measured against the error of Embree's float
//    barycentrics, which grows with the vertices' distance from the ray origin and falls with the
//    triangle's area: a long sliver's hit 1.6e-5 inside an edge in barycentrics can be outside it
//    (grids with the 4x light had one such false block with a fixed 1e-5 margin).
//  - Each triangle is handed to Embree starting at its shortest edge (fillBuffers()), with
//    the winding kept; the filter's rule still reads the vertices in stream order. Embree's test
//    works relative to the first vertex, and from a long sliver's far tip it rounded the edge
//    functions near the short edge badly enough to miss hits 3e-3 rad inside, as seen from the
//    receiver (two relations of grids 1280x960 with the 4x light). RTC_SCENE_FLAG_ROBUST finds
//    them too, but costs 2.5x the trace time, which would not be a fair peer.
//  - What can still differ: a triangle the rule blocks but Embree's float test never reports,
//    i.e. a segment within float roundoff of one of its edges. Those are ties of the rule's edge
//    test (bake/TieClassifier.h). Embree never blocks a relation the rule does not.
//  - The ray: from r, tnear = eps(r) / 2 along the ray (a triangle the rule counts is at least
//    eps(r) away along the ray, since distance along the ray is never below the perpendicular
//    distance), to just beyond the sample (tfar = 1 + 1e-5 of l - r; the filter rejects hits
//    beyond l) or, for a direction, to infinity.
//  - Degenerate relations (l == r, non-finite receivers) are not traced and count as unblocked,
//    which is what the rule gives for them too.
//
// Build quality: RTC_BUILD_QUALITY_HIGH (spatial-split SAH BVH), the setting Embree recommends for
// static, final-frame scenes. A bake builds once and traces receivers x samples rays (typically
// hundreds of rays per triangle), so the slower commit is repaid by faster traversal. The cost is
// a larger BVH (split references); sceneBytes reports only the vertex and index buffers.

#include "bake/rule/AlphaRule.h"
#include "bake/cast/SceneCaster.h"
#include "stream/util/Error.h"
#include "stream/Translucency.h"

#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#if defined(__SSE__) || defined(_M_X64)
#include <pmmintrin.h>
#include <xmmintrin.h>
#define PENUMBRA_HAVE_MXCSR 1
#endif

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <string>

namespace penumbra {
namespace {


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
/// Rays to a point sample end just beyond it (in units of l - r); the filter rejects what lies
/// beyond the sample, so this only has to be past Embree's float rounding of t = 1.
constexpr float kTfarPoint = 1.0f + 1e-5f;
/// Without the filter, rays end just before the sample, so the sample itself is excluded.
constexpr float kTfarNative = 1.0f - 1e-6f;

/// The triangles Embree gets: finite, with non-zero area (the rule's BlockerTriangle::valid),
/// casting, and translucent ones only when @p translucent.
std::vector<const Triangle*> validTriangles(std::span<const Triangle> triangles, bool translucent) {
    std::vector<const Triangle*> kept;
    kept.reserve(triangles.size());
    for (const Triangle& t : triangles)
        if (isFinite(t) && !(t.flags & kTriangleNoCast) && (translucent || blocksAsOpaque(t.flags)) && BlockerTriangle::from(t).valid)
            kept.push_back(&t);
    if (kept.size() > size_t(std::numeric_limits<uint32_t>::max()) / 3)
        fail("embree", "{} triangles exceed the 32-bit vertex index range of one Embree geometry", kept.size());
    return kept;
}

/// What the filter reads per primitive: one load for both.
struct PrimitiveInfo {
    uint32_t alphaId = 0;     ///< 0: opaque
    float longestEdge = 0.0f; ///< bounds the vertices' distance from a hit (certainlyBlocks())
};

/// Copies @p kept (non-empty) into Embree-allocated buffers, which carry the padding Embree needs
/// for vector loads of the last vertex, and describes each triangle in @p primitives. Vertices
/// are not shared: three per triangle, in stream order (the filter's rule reads them so). The
/// indices start each triangle at its shortest edge, winding kept: Embree's test works relative
/// to the first vertex, and anchoring it there keeps a long sliver's edge functions small where
/// the sliver is wide, and with them the rounding.
void fillBuffers(RTCGeometry geometry, const std::vector<const Triangle*>& kept, std::vector<PrimitiveInfo>& primitives) {
    const size_t n = kept.size();
    auto* vertices = static_cast<float*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * n));
    auto* indices = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), n));
    if (!vertices || !indices) return;  // the error function has the reason
    primitives.reserve(n);
    for (size_t i = 0; i < n; ++i) {
        const Triangle& t = *kept[i];
        float edge[3];
        for (int e = 0; e < 3; ++e) edge[e] = glm::length(t.v[(e + 1) % 3] - t.v[e]);
        const int first = int(std::min_element(edge, edge + 3) - edge);
        primitives.push_back({alphaIdOf(t.flags), *std::max_element(edge, edge + 3) * (1.0f + 0x1p-20f)});  // rounded up
        for (int c = 0; c < 3; ++c) {
            const glm::vec3& v = kept[i]->v[c];
            vertices[9 * i + 3 * c + 0] = v.x;
            vertices[9 * i + 3 * c + 1] = v.y;
            vertices[9 * i + 3 * c + 2] = v.z;
            indices[3 * i + c] = uint32_t(3 * i + (first + c) % 3);
        }
    }
}

/// One packet being filled: lane i answers bit laneBit[i] of word laneWord[i] of the receiver row.
/// The filter reads the relation's exact inputs: the sample (and its weight) per lane, and the
/// receiver and its epsilon, shared by the packet (packets never span receivers).
struct Packet {
    RTCRay16 ray;  // RTC_ALIGN(64)
    alignas(64) int valid[kPacket];
    int laneWord[kPacket];
    int laneBit[kPacket];
    glm::dvec3 sample[kPacket];
    double w[kPacket];
    glm::dvec3 receiver{0.0};
    double eps = 0.0;
    int lanes = 0;
    /// Per lane: the optical depth of the translucent triangles crossed so far, and which.
    uint32_t depth[kPacket][3];
    std::vector<uint32_t> crossed[kPacket];

    Packet() { reset(); }
    void reset() {
        lanes = 0;
        for (int i = 0; i < kPacket; ++i) {
            valid[i] = 0;
            depth[i][0] = depth[i][1] = depth[i][2] = 0;
            crossed[i].clear();
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

/// The intersect context Embree hands to the filter, extended with the packet being traced
/// (Embree passes the pointer through unchanged; RTCIntersectContext must come first).
struct FilterContext {
    RTCIntersectContext context;
    Packet* packet = nullptr;
    const float* vertices = nullptr;  ///< the geometry's vertex buffer: 9 floats per triangle
    const PrimitiveInfo* primitives = nullptr;  ///< per primitive: alpha id and longest edge
    const AlphaTable* alpha = nullptr;
    bool ruleFilter = true;              ///< opaque hits get the rule too (else they are accepted)
    uint64_t calls = 0, exact = 0, rejected = 0;
};

/// True when Embree's own hit is so far inside the triangle, behind the receiver's epsilon band
/// and (for a point) before the sample that the rule certainly blocks too: margins many times
/// the float roundoff of the hit's barycentrics and distances. Most hits take this path, so the
/// filter costs Embree little; the rest get the rule itself.
///
/// Barycentrics: Embree's u, v are float edge functions of the vertices taken relative to the ray
/// origin o, divided by Ng . d (Ng = e1 x e2, |Ng| = twice the area). Their absolute error is
/// below a small multiple of 2^-24 |d| R (R + M) / |Ng . d|, with R >= |v_i - o| (reach) and
/// M >= |v_i| (magnitude); the float rounding of d moves the hit by less than that too. The
/// margin is 16 times it (and sqrt(3) for taking norms from the inf-norm scale): a sliver seen
/// from near its short edge needs a large one. On grids at 640x480 this sends 2 % of the filter's
/// calls to the rule (0.03 % with a fixed 1e-5), for about 3 % more trace time.
bool certainlyBlocks(const RTCFilterFunctionNArguments* args, unsigned i, const Packet& packet, unsigned lane,
                     float longestEdge) {
    const unsigned n = args->N;
    const float u = RTCHitN_u(args->hit, n, i), v = RTCHitN_v(args->hit, n, i);
    const double innermost = std::min({u, v, 1.0f - u - v});
    if (!(innermost >= 1e-5)) return false;
    const glm::dvec3 ng(RTCHitN_Ng_x(args->hit, n, i), RTCHitN_Ng_y(args->hit, n, i), RTCHitN_Ng_z(args->hit, n, i));
    const glm::dvec3 d(RTCRayN_dir_x(args->ray, n, i), RTCRayN_dir_y(args->ray, n, i), RTCRayN_dir_z(args->ray, n, i));
    const double t = RTCRayN_tfar(args->ray, n, i), ngLength = glm::length(ng), dLength = glm::length(d);
    if (!(ngLength > 0.0 && dLength > 0.0)) return false;
    const double cosine = std::abs(glm::dot(ng, d)) / (ngLength * dLength);
    const glm::dvec3 hit = packet.receiver + t * d;
    const double scale = std::max({std::abs(hit.x), std::abs(hit.y), std::abs(hit.z), std::abs(packet.receiver.x),
                                   std::abs(packet.receiver.y), std::abs(packet.receiver.z)});
    const double reach = t * dLength + double(longestEdge), magnitude = scale + double(longestEdge);
    constexpr double kBarycentricMargin = 16 * 0x1p-24 * 1.7320508075688772;
    if (!(innermost * ngLength * cosine >= kBarycentricMargin * reach * (reach + magnitude))) return false;
    const double roundoff = 64 * 0x1p-24 * scale;
    if (!(t * dLength * cosine >= 2.0 * packet.eps + roundoff)) return false;  // behind the band
    return packet.w[lane] == 0.0 || (1.0 - t) * dLength * cosine >= roundoff;  // before the sample
}

/// A hit on translucent primitive @p prim of lane @p lane that the rule counts: its depth is
/// added once per ray, whatever times Embree reports it.
void crossTranslucent(Packet& packet, unsigned lane, uint32_t prim, uint32_t alphaId) {
    std::vector<uint32_t>& seen = packet.crossed[lane];
    if (std::find(seen.begin(), seen.end(), prim) != seen.end()) return;
    seen.push_back(prim);
    const OpticalDepth& d = opticalDepthOf(alphaId);
    for (int c = 0; c < 3; ++c) packet.depth[lane][c] = addDepth(packet.depth[lane][c], d[c]);
}

/// Accepts a candidate hit only when the blocking rule blocks the relation with that triangle;
/// a translucent triangle's hit is never accepted (the ray goes on), its depth is added.
void ruleFilter(const RTCFilterFunctionNArguments* args) {
    auto* fc = reinterpret_cast<FilterContext*>(args->context);
    Packet& packet = *fc->packet;
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] == 0) continue;
        const unsigned lane = RTCRayN_id(args->ray, args->N, i);
        const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
        const PrimitiveInfo info = fc->primitives[prim];
        const uint32_t alphaId = info.alphaId;
        if (!alphaId && !fc->ruleFilter) continue;  // Embree's native answer for opaque triangles
        ++fc->calls;
        if (!alphaId && certainlyBlocks(args, i, packet, lane, info.longestEdge)) continue;
        ++fc->exact;
        const float* v = fc->vertices + 9 * size_t(prim);
        Triangle tri{{glm::vec3(v[0], v[1], v[2]), glm::vec3(v[3], v[4], v[5]), glm::vec3(v[6], v[7], v[8])},
                     withAlphaId(0, alphaId)};
        const BlockerTriangle t = BlockerTriangle::from(tri);
        bool blocked = false;
        const bool translucent = isTranslucentId(alphaId);
        if (t.valid) {
            const HardShadowVolume h = makeHardShadowVolume(packet.sample[lane], packet.w[lane], t);
            blocked = translucent ? blocks(h, t, packet.receiver, distanceBehind(t, packet.receiver), packet.eps)
                                  : blocksWithAlpha(h, t, packet.receiver, distanceBehind(t, packet.receiver), packet.eps, *fc->alpha);
        }
        if (translucent && blocked) crossTranslucent(packet, lane, prim, alphaId), blocked = false;
        if (!blocked) args->valid[i] = 0, ++fc->rejected;
    }
}

}  // namespace

namespace {

/// Embree's device, scene and what the filter reads, built over the valid triangles.
/// Member order matters: the error state outlives the device, the device outlives the scene
/// (members are destroyed in reverse order, on every path, including throws). Not movable: the
/// device's error callback holds the error state's address.
struct EmbreeBvh {
    ErrorState errors;
    DeviceHandle device;
    SceneHandle scene;
    const float* vertices = nullptr;  ///< owned by the geometry, which the scene keeps alive
    std::vector<PrimitiveInfo> primitives;  ///< per primitive, for the filter
    uint64_t sceneBytes = 0;
};

/// Builds @p bvh (device, scene and BVH) over the valid triangles of @p triangles.
/// @throw InputError "embree: ..." when Embree reports an error or culls back faces.
void buildBvh(EmbreeBvh& bvh, std::span<const Triangle> triangles, bool ruleFilter, bool translucent) {
    bvh.device.device = rtcNewDevice(nullptr);
    if (!bvh.device.device) fail("embree", "{} creating the device", errorName(rtcGetDeviceError(nullptr)));
    RTCDevice device = bvh.device.device;
    rtcSetDeviceErrorFunction(device, &ErrorState::callback, &bvh.errors);
    bvh.errors.check(device, "device creation");
    // A shadow ray must be blocked from both sides of a triangle.
    if (rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED))
        fail("embree", "this Embree library was built with backface culling, which shadow rays cannot use");

    bvh.scene.scene = rtcNewScene(device);
    bvh.errors.check(device, "scene creation");
    rtcSetSceneFlags(bvh.scene.scene, RTC_SCENE_FLAG_NONE);  // see the top of this file
    rtcSetSceneBuildQuality(bvh.scene.scene, RTC_BUILD_QUALITY_HIGH);
    {
        const std::vector<const Triangle*> kept = validTriangles(triangles, translucent);  // freed before tracing
        bvh.sceneBytes = uint64_t(kept.size()) * (9 * sizeof(float) + 3 * sizeof(uint32_t) + sizeof(PrimitiveInfo));
        if (!kept.empty()) {  // an empty scene needs no geometry (and Embree gets no zero-sized buffers)
            GeometryHandle geometry;
            geometry.geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
            bvh.errors.check(device, "geometry creation");
            rtcSetGeometryBuildQuality(geometry.geometry, RTC_BUILD_QUALITY_HIGH);
            fillBuffers(geometry.geometry, kept, bvh.primitives);
            bvh.errors.check(device, "buffer allocation");
            const bool anyAlpha = std::any_of(bvh.primitives.begin(), bvh.primitives.end(), [](const PrimitiveInfo& p) { return p.alphaId != 0; });
            bvh.vertices = static_cast<const float*>(rtcGetGeometryBufferData(geometry.geometry, RTC_BUFFER_TYPE_VERTEX, 0));
            if (ruleFilter || anyAlpha) rtcSetGeometryOccludedFilterFunction(geometry.geometry, ::penumbra::ruleFilter);
            rtcCommitGeometry(geometry.geometry);
            rtcAttachGeometry(bvh.scene.scene, geometry.geometry);  // the scene holds its own reference
            bvh.errors.check(device, "geometry commit");
        }
    }
    rtcCommitScene(bvh.scene.scene);
    bvh.errors.check(device, "BVH build");
}

/// One receiver's shadow rays, 16 at a time (packets never span receivers: the row being
/// written is @p row's), into its mask words. @return the rays traced.
uint64_t traceReceiver(RTCScene scene, FilterContext& fc, Packet& packet, const LightSamples& samples, int set,
                       const glm::vec3& p, double eps, bool ruleFilter, uint64_t* row, std::unique_ptr<uint32_t[]>* depths) {
    const glm::dvec3 pd(p);
    packet.receiver = pd, packet.eps = eps;
    auto flush = [&] {
        if (packet.lanes == 0) return;
        rtcOccluded16(packet.valid, scene, &fc.context, &packet.ray);
        for (int i = 0; i < packet.lanes; ++i) {
            if (packet.valid[i] && packet.ray.tfar[i] == -std::numeric_limits<float>::infinity()) {
                row[packet.laneWord[i]] |= 1ull << packet.laneBit[i];
                continue;  // blocked: what it crossed before does not matter
            }
            const uint32_t* d = packet.depth[i];
            if (!depths || !(d[0] | d[1] | d[2])) continue;
            if (!*depths) *depths = std::make_unique<uint32_t[]>(size_t(samples.sampleCount) * 3);  // zeroed
            const size_t sample = samples.groups[size_t(packet.laneWord[i])].first + uint32_t(packet.laneBit[i]);
            std::copy(d, d + 3, depths->get() + 3 * sample);
        }
        packet.reset();
    };
    uint64_t traced = 0;
    for (int k = 0; k < samples.groupCount(); ++k) {
        const LightSampleGroup& g = samples.groups[k];
        const double w = samples.w(g.light);
        for (uint32_t j = 0; j < g.count; ++j) {
            const glm::dvec3 l(samples.position(set, int(g.first + j)));
            const glm::dvec3 d = l - w * pd;  // towards the point, or the direction itself
            const double len = glm::length(d);
            if (!(len > 0.0) || !std::isfinite(len)) continue;
            const float tnear = float((ruleFilter ? 0.5 : 1.0) * eps / len);
            const float tfar = w == 0.0 ? std::numeric_limits<float>::infinity() : (ruleFilter ? kTfarPoint : kTfarNative);
            if (!(tnear < tfar)) continue;
            const int i = packet.lanes++;
            packet.valid[i] = -1;
            packet.laneWord[i] = k;
            packet.laneBit[i] = int(j);
            packet.sample[i] = l;
            packet.w[i] = w;
            packet.ray.org_x[i] = p.x;
            packet.ray.org_y[i] = p.y;
            packet.ray.org_z[i] = p.z;
            packet.ray.dir_x[i] = float(d.x);
            packet.ray.dir_y[i] = float(d.y);
            packet.ray.dir_z[i] = float(d.z);
            packet.ray.tnear[i] = tnear;
            packet.ray.tfar[i] = tfar;
            ++traced;
            if (packet.lanes == kPacket) flush();
        }
    }
    flush();
    return traced;
}

/// Embree's rays hold coordinates and direction components up to its FLT_LARGE (1.844e18); a ray
/// beyond that fails an assertion inside Embree, which aborts. Lights stay within 1e15 of the
/// origin (the scene refuses more), so a receiver within half of it keeps l - r within it too.
constexpr double kEmbreeRayRange = 0.9e18;

void checkRayRange(const ReceiverSet& receivers) {
    for (size_t r = 0; r < receivers.size(); ++r) {
        const glm::vec3& p = receivers.position[r];
        if (std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}) > kEmbreeRayRange)
            fail("--method embree", "receiver {} at ({:.3g}, {:.3g}, {:.3g}) is beyond the range of Embree's rays (coordinates up "
                 "to {:.2g}); use another method", r, p.x, p.y, p.z, kEmbreeRayRange);
    }
}

}  // namespace

VisibilityMasks castEmbree(const LightSamples& samples, const ReceiverSet& receivers,
                           std::span<const uint32_t> sampleSetOf, std::span<const Triangle> triangles,
                           const ReceiverEpsilon& epsilon, EmbreeStats* stats,
                           const std::function<void(uint64_t)>& progress, bool ruleFilter, const AlphaTable* alpha,
                           std::vector<std::unique_ptr<uint32_t[]>>* depths) {
    checkRayRange(receivers);
    EmbreeStats local;
    if (!alpha) alpha = AlphaTable::builtin().get();
    const Stopwatch buildWatch;
    DenormalsOff denormals;  // the calling thread takes part in the build and in parallel_for
    EmbreeBvh bvh;
    buildBvh(bvh, triangles, ruleFilter, depths != nullptr);
    if (depths) depths->clear(), depths->resize(receivers.size());
    local.sceneBytes = bvh.sceneBytes;
    local.buildSeconds = buildWatch.seconds();

    const Stopwatch traceWatch;
    VisibilityMasks masks(receivers.size(), samples.groupCount());
    std::atomic<uint64_t> rays{0}, filterCalls{0}, filterExact{0}, filterRejected{0};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, receivers.size(), 16), [&](const tbb::blocked_range<size_t>& range) {
        DenormalsOff threadDenormals;
        Packet packet;
        FilterContext fc;
        rtcInitIntersectContext(&fc.context);
        // Incoherent, although one receiver's rays share their origin: with the coherent flag
        // Embree traced a packet through one frustum, which for a narrow sun's near-parallel rays
        // culled a flat BVH box (a box's top) that every ray crossed, and left real blocks lit.
        // Incoherent packets were as fast on GRIDS and SPONZA-LIKE (docs/BENCHMARKS.md).
        fc.context.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
        fc.packet = &packet;
        fc.vertices = bvh.vertices;
        fc.primitives = bvh.primitives.data();
        fc.alpha = alpha;
        fc.ruleFilter = ruleFilter;
        uint64_t traced = 0;
        for (size_t r = range.begin(); r != range.end(); ++r) {
            const glm::vec3 p = receivers.position[r];
            const glm::dvec3 pd(p);
            if (!std::isfinite(pd.x) || !std::isfinite(pd.y) || !std::isfinite(pd.z)) continue;
            traced += traceReceiver(bvh.scene.scene, fc, packet, samples, int(sampleSetOf[r]), p, epsilon.at(pd), ruleFilter,
                                    masks.row(r), depths ? &(*depths)[r] : nullptr);
        }
        rays.fetch_add(traced, std::memory_order_relaxed);
        filterCalls.fetch_add(fc.calls, std::memory_order_relaxed);
        filterExact.fetch_add(fc.exact, std::memory_order_relaxed);
        filterRejected.fetch_add(fc.rejected, std::memory_order_relaxed);
        if (progress) progress(range.size());
    });
    bvh.errors.check(bvh.device.device, "tracing");
    local.traceSeconds = traceWatch.seconds();
    local.rays = rays.load();
    local.filterCalls = filterCalls.load();
    local.filterExact = filterExact.load();
    local.filterRejected = filterRejected.load();
    if (stats) *stats = local;
    return masks;
}

}  // namespace penumbra

namespace penumbra {
namespace {

/// Embree over the whole scene, with its own stats (build and trace times, rays, filter calls).
class EmbreeSceneCaster final : public SceneCaster {
public:
    explicit EmbreeSceneCaster(const CastContext& c)
        : SceneCaster(c, "embree", [this](const ReceiverSet& targets, std::span<const uint32_t> sets,
                                          std::span<const Triangle> all, const std::function<void(uint64_t)>& progress) {
              EmbreeStats s;
              VisibilityMasks m = castEmbree(c_.samples, targets, sets, all, receiverEpsilonOf(c_.options), &s, progress,
                                             c_.options.embreeRuleFilter, &alphaTableOf(c_.options), &depths_);
              stats_.buildSeconds += s.buildSeconds, stats_.traceSeconds += s.traceSeconds, stats_.rays += s.rays;
              stats_.sceneBytes = s.sceneBytes, stats_.filterCalls += s.filterCalls;
              stats_.filterExact += s.filterExact, stats_.filterRejected += s.filterRejected;
              return m;
          }) {}

    nlohmann::json methodStats() const override {
        return {{"build_time_s", stats_.buildSeconds}, {"trace_time_s", stats_.traceSeconds},
                {"rays", stats_.rays},                {"scene_bytes", stats_.sceneBytes},
                {"filter_calls", stats_.filterCalls}, {"filter_exact", stats_.filterExact},
                {"filter_rejected", stats_.filterRejected}};
    }

private:
    EmbreeStats stats_;
};

const CasterRegistration kEmbree{{"embree",
                                  {.holdsScene = true, .translucency = true,
                                   .summary = "Intel Embree 3 shadow rays over the same receivers and samples"},
                                  [](const CastContext& c) { return std::make_unique<EmbreeSceneCaster>(c); },
                                  [](uint64_t triangles, uint64_t, const LightSamples&, const nlohmann::json&) {
                                      // The scene read once, Embree's buffers and an estimate of its BVH
                                      // (Embree does not report the BVH's size), and the address space its
                                      // allocator maps beyond what it touches: under prlimit --as the limit
                                      // named without them failed inside Embree until 40-48 MiB + 48 bytes a
                                      // triangle more (63K to 483K triangles, two threads; 56 MiB keeps a margin).
                                      return triangles * (sizeof(Triangle) + 56 + 120 + 48) + (56ull << 20);
                                  },
                                  nullptr}};

}  // namespace
}  // namespace penumbra
