#include "bake/methods/SsvKernels.h"

// An AVX2 clone and a default one, picked at load time by an ifunc resolver. ThreadSanitizer
// crashes in a resolver (it runs before the sanitizer's runtime starts), so its builds take the
// default code only.
#if defined(__SANITIZE_THREAD__)
#define PENUMBRA_AVX2_CLONES
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define PENUMBRA_AVX2_CLONES
#endif
#endif
#ifndef PENUMBRA_AVX2_CLONES
#define PENUMBRA_AVX2_CLONES __attribute__((target_clones("avx2", "default")))
#endif

namespace penumbra {

PENUMBRA_AVX2_CLONES void ssvIntegrateSamples(const SsvEdgeTerm& t, uint32_t n, const double* lx,
                                                                           const double* ly, const double* lz, const double* dx,
                                                                           const double* dy, const double* dz, int* depth) {
    const double wax = t.wa.x, way = t.wa.y, waz = t.wa.z, bax = t.ba.x, bay = t.ba.y, baz = t.ba.z;
    const double rax = t.ra.x, ray = t.ra.y, raz = t.ra.z, s = t.s;
    const double qax = t.qa.x, qay = t.qa.y, qaz = t.qa.z, qbx = t.qb.x, qby = t.qb.y, qbz = t.qb.z;
    const int ref = t.refInside;
    for (uint32_t j = 0; j < n; ++j) {
        const double sa = qax * dx[j] + qay * dy[j] + qaz * dz[j];
        const double sb = qbx * dx[j] + qby * dy[j] + qbz * dz[j];
        const double x = lx[j] - wax, y = ly[j] - way, z = lz[j] - waz;
        const double cx = y * baz - bay * z, cy = z * bax - baz * x, cz = x * bay - bax * y;
        const double e = s * (cx * rax + cy * ray + cz * raz);
        const int separated = (sa > 0.0) != (sb > 0.0);
        depth[j] += separated * (int(e >= 0.0) - ref);
    }
}

PENUMBRA_AVX2_CLONES void ssvStraddlerSamples(const BlockerTriangle& t, double w,
                                                                           const glm::dvec3& r, double distance,
                                                                           double eps, uint32_t n, const double* lx,
                                                                           const double* ly, const double* lz,
                                                                           uint8_t* blocked) {
    const glm::dvec3 n0 = t.plane.n, wv0 = w * t.v[0];
    glm::dvec3 wa[3], ba[3], ra[3];
    for (int e = 0; e < 3; ++e) wa[e] = w * t.v[e], ba[e] = t.v[(e + 1) % 3] - t.v[e], ra[e] = r - t.v[e];
    for (uint32_t j = 0; j < n; ++j) {
        // makeHardShadowVolume: the sample's side, then each edge plane, in the rule's order.
        const double side = n0.x * (lx[j] - wv0.x) + n0.y * (ly[j] - wv0.y) + n0.z * (lz[j] - wv0.z);
        const double hside = side > 0.0 ? -1.0 : 1.0;
        int inside = (side > 0.0 || side < 0.0) & (hside * distance > eps);
        for (int e = 0; e < 3; ++e) {
            const double x = lx[j] - wa[e].x, y = ly[j] - wa[e].y, z = lz[j] - wa[e].z;
            const double cx = y * ba[e].z - ba[e].y * z, cy = z * ba[e].x - ba[e].z * x, cz = x * ba[e].y - ba[e].x * y;
            inside &= -hside * (cx * ra[e].x + cy * ra[e].y + cz * ra[e].z) >= 0.0;
        }
        blocked[j] |= uint8_t(inside);
    }
}

}  // namespace penumbra
