#include "bake/shading/ReceiverShading.h"

#include "bake/light/SunLight.h"

#include "stream/Translucency.h"
#include "stream/util/Error.h"
#include "stream/util/Progress.h"

#include <glm/geometric.hpp>
#include <glm/gtc/constants.hpp>

#include <immintrin.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>

namespace penumbra {
namespace {

/// Lights with at most this many samples are shaded from a visibility bit mask on the stack.
constexpr size_t kMaxMaskedSamples = 4096;

/// The per-channel transmittance of one sample's optical depths @p d (R, G, B).
glm::dvec3 transmittance(const uint32_t* d) { return {transmittanceOf(d[0]), transmittanceOf(d[1]), transmittanceOf(d[2])}; }

/// Whether the shading's AVX2 paths run (they give the scalar paths' bits).
bool hasAvx2() {
    static const bool avx2 = __builtin_cpu_supports("avx2");
    return avx2;
}

/// transmittance() of the last depths asked for, kept: neighbouring samples mostly cross the same
/// panes, so each distinct depth's exp2 is computed once.
class TransmittanceMemo {
public:
    const glm::dvec3& of(const uint32_t* d) {
        if (!std::equal(d, d + 3, last_)) value_ = transmittance(d), std::copy(d, d + 3, last_);
        return value_;
    }

private:
    uint32_t last_[3] = {0, 0, 0};
    glm::dvec3 value_{1.0};  ///< the transmittance of depth 0
};

}  // namespace

glm::dvec3 radianceFromPower(const LightDesc& l, const glm::dvec3& power) {
    const double pi = glm::pi<double>();
    switch (l.type) {
        case LightType::Sun: fail(l.where, "a sun takes \"irradiance\" or \"radiance\", not \"power\"");
        // A Lambertian sphere of radiance L emits L * pi per unit area over 4 pi r^2.
        case LightType::Sphere: return power / (4.0 * pi * pi * l.radius * l.radius);
        default: return power / (pi * l.area());  // one-sided Lambertian emitter
    }
}

ReceiverShader::ReceiverShader(const std::vector<LightDesc>& lights, const LightSamples& samples,
                               const ReceiverSet& receivers, std::span<const uint32_t> sampleSets)
    : samples_(samples), receivers_(receivers), sets_(sampleSets) {
    for (const LightDesc& l : lights) {
        PerLight p;
        p.samples = l.samples;
        if (l.type == LightType::Sun) {
            // Every sample is a direction carrying an equal share of the sun's irradiance, scaled so
            // that a surface facing the sun receives all of it (sunMeanCosine()).
            p.sun = true, p.normal = glm::dvec3(0.0), p.weight = l.irradiance / (double(l.samples) * sunMeanCosine(l.angularDiameterDeg));
        } else {
            // A sphere is seen as a disk of its radius from every direction.
            double area = l.type == LightType::Sphere ? M_PI * l.radius * l.radius : l.area();
            p.normal = l.emitterNormal(), p.weight = l.radiance * (area / l.samples);
            p.radiance = l.radiance, p.corners = l.outline();
        }
        lights_.push_back(p);
    }
}

namespace {

/// One sample's (cos receiver) (cos emitter) / d^2 (planar emitters), cos / d^2 (volumes) or cos
/// (directions), in the operation order of sampleSumAvx2()'s lanes.
inline double sampleTerm(double x, double y, double z, glm::dvec3 p, glm::dvec3 normal, glm::dvec3 emitter) {
    const double dx = x - p.x, dy = y - p.y, dz = z - p.z;
    const double d2 = std::max(dx * dx + dy * dy + dz * dz, 1e-300);  // d = 0 gives zero cosines
    const double inv = 1.0 / std::sqrt(d2);
    const double cr = std::max(0.0, (normal.x * dx + normal.y * dy + normal.z * dz) * inv);
    const double ce = std::max(0.0, -(emitter.x * dx + emitter.y * dy + emitter.z * dz) * inv);
    return cr * ce / d2;
}

/// Whether sample @p j is in @p visible (every sample is when it is null).
inline bool isVisible(const uint64_t* visible, size_t j) { return !visible || (visible[j >> 6] >> (j & 63) & 1u); }

/// Sum over samples [0, n) of the SoA arrays of sampleTerm(), over the samples set in @p visible
/// (all of them when it is null): lightIrradiance's terms without weights. Four partial sums,
/// sample j in sum j % 4, in a fixed order; the AVX2 path below computes the same lanes with the
/// same correctly rounded operations (no fused multiply-add), so both give the same bits. A
/// hidden sample adds nothing (the sums start at +0 and no term is negative).
double sampleSumScalar(const double* x, const double* y, const double* z, size_t n, glm::dvec3 p, glm::dvec3 normal,
                       glm::dvec3 emitter, const uint64_t* visible) {
    double lanes[4] = {0, 0, 0, 0};
    for (size_t j = 0; j < n; ++j)
        if (isVisible(visible, j)) lanes[j % 4] += sampleTerm(x[j], y[j], z[j], p, normal, emitter);
    return (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
}

/// sampleTerm() of four consecutive samples, with the same correctly rounded operations in each
/// lane (no fused multiply-add), so the same bits.
struct SampleTermsAvx2 {
    __m256d px, py, pz, nx, ny, nz, ex, ey, ez, tiny, one, zero;
    __attribute__((target("avx2"))) SampleTermsAvx2(glm::dvec3 p, glm::dvec3 normal, glm::dvec3 emitter)
        : px(_mm256_set1_pd(p.x)), py(_mm256_set1_pd(p.y)), pz(_mm256_set1_pd(p.z)), nx(_mm256_set1_pd(normal.x)),
          ny(_mm256_set1_pd(normal.y)), nz(_mm256_set1_pd(normal.z)), ex(_mm256_set1_pd(-emitter.x)), ey(_mm256_set1_pd(-emitter.y)),
          ez(_mm256_set1_pd(-emitter.z)), tiny(_mm256_set1_pd(1e-300)), one(_mm256_set1_pd(1.0)), zero(_mm256_setzero_pd()) {}
    __attribute__((target("avx2"))) __m256d at(const double* x, const double* y, const double* z) const {
        const __m256d dx = _mm256_sub_pd(_mm256_loadu_pd(x), px), dy = _mm256_sub_pd(_mm256_loadu_pd(y), py),
                      dz = _mm256_sub_pd(_mm256_loadu_pd(z), pz);
        const __m256d d2 = _mm256_max_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)), _mm256_mul_pd(dz, dz)), tiny);
        const __m256d inv = _mm256_div_pd(one, _mm256_sqrt_pd(d2));
        const __m256d dn = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(nx, dx), _mm256_mul_pd(ny, dy)), _mm256_mul_pd(nz, dz));
        // -(e . d) as (-e.x) dx + (-e.y) dy + (-e.z) dz: negation commutes with rounding.
        const __m256d de = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(ex, dx), _mm256_mul_pd(ey, dy)), _mm256_mul_pd(ez, dz));
        const __m256d cr = _mm256_max_pd(_mm256_mul_pd(dn, inv), zero), ce = _mm256_max_pd(_mm256_mul_pd(de, inv), zero);
        return _mm256_div_pd(_mm256_mul_pd(cr, ce), d2);
    }
};

__attribute__((target("avx2"))) double sampleSumAvx2(const double* x, const double* y, const double* z, size_t n, glm::dvec3 p,
                                                     glm::dvec3 normal, glm::dvec3 emitter, const uint64_t* visible) {
    const SampleTermsAvx2 terms(p, normal, emitter);
    const __m256d zero = terms.zero;
    const __m256i laneBits = _mm256_setr_epi64x(1, 2, 4, 8);
    __m256d acc = zero;
    size_t j = 0;
    for (; j + 4 <= n; j += 4) {
        const uint64_t nibble = visible ? visible[j >> 6] >> (j & 63) & 15u : 15u;  // j % 4 == 0: within one word
        if (!nibble) continue;  // a receiver in shadow skips its hidden samples four at a time
        const __m256d term = terms.at(x + j, y + j, z + j);
        const __m256i shown = _mm256_cmpeq_epi64(_mm256_and_si256(_mm256_set1_epi64x(int64_t(nibble)), laneBits), laneBits);
        acc = _mm256_add_pd(acc, _mm256_and_pd(term, _mm256_castsi256_pd(shown)));
    }
    alignas(32) double lanes[4];
    _mm256_store_pd(lanes, acc);
    for (; j < n; ++j)  // the tail, into the lanes the scalar loop would use
        if (isVisible(visible, j)) lanes[j % 4] += sampleTerm(x[j], y[j], z[j], p, normal, emitter);
    return (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
}

/// Sum over samples [0, n) of the SoA arrays of (cos receiver) (cos emitter) / d^2, over the
/// samples in @p visible (null: all): the terms of lightIrradiance for a planar emitter, without
/// its weight.
double sampleSum(const double* x, const double* y, const double* z, size_t n, glm::dvec3 p, glm::dvec3 normal, glm::dvec3 emitter,
                 const uint64_t* visible = nullptr) {
    return hasAvx2() ? sampleSumAvx2(x, y, z, n, p, normal, emitter, visible) : sampleSumScalar(x, y, z, n, p, normal, emitter, visible);
}

/// Σ T_j term_j over the visible samples [0, n), in sample order: sampleSum()'s terms, each tinted
/// by its sample's transmittance (@p depth: 3 depths per sample). The AVX2 path computes the terms
/// four at a time with sampleTerm()'s bits and adds them in the same order, so both agree.
glm::dvec3 tintedSampleSumScalar(const double* x, const double* y, const double* z, size_t n, glm::dvec3 p, glm::dvec3 normal,
                                 glm::dvec3 emitter, const uint64_t* visible, const uint32_t* depth) {
    glm::dvec3 sum(0.0);
    TransmittanceMemo t;
    for (size_t j = 0; j < n; ++j)
        if (isVisible(visible, j)) sum += t.of(depth + 3 * j) * sampleTerm(x[j], y[j], z[j], p, normal, emitter);
    return sum;
}

__attribute__((target("avx2"))) glm::dvec3 tintedSampleSumAvx2(const double* x, const double* y, const double* z, size_t n,
                                                               glm::dvec3 p, glm::dvec3 normal, glm::dvec3 emitter,
                                                               const uint64_t* visible, const uint32_t* depth) {
    const SampleTermsAvx2 terms(p, normal, emitter);
    glm::dvec3 sum(0.0);
    TransmittanceMemo t;
    alignas(32) double lanes[4];
    size_t j = 0;
    for (; j + 4 <= n; j += 4) {
        uint64_t nibble = visible[j >> 6] >> (j & 63) & 15u;  // j % 4 == 0: within one word
        if (!nibble) continue;
        _mm256_store_pd(lanes, terms.at(x + j, y + j, z + j));
        for (; nibble; nibble &= nibble - 1) {
            const int i = std::countr_zero(nibble);
            sum += t.of(depth + 3 * (j + size_t(i))) * lanes[i];
        }
    }
    for (; j < n; ++j)
        if (isVisible(visible, j)) sum += t.of(depth + 3 * j) * sampleTerm(x[j], y[j], z[j], p, normal, emitter);
    return sum;
}

/// atan2(@p y, @p x) for y >= 0 (an angle in [0, pi]) within 3e-8 rad: Abramowitz & Stegun
/// 4.4.49's polynomial for atan on [0, 1], folded. libm's atan2 was a fifth of the shading time
/// of a penumbra-map preview, four calls per receiver, where 1e-7 of irradiance is far below
/// what the method resolves.
double angleOf(double y, double x) {
    const double ax = std::abs(x);
    if (!(y > 0) && !(ax > 0)) return 0.0;
    const bool steep = y > ax;
    const double t = steep ? ax / y : y / ax, t2 = t * t;
    double a = -0.0040540580;
    for (const double c : {0.0218612288, -0.0559098861, 0.0964200441, -0.1390853351, 0.1994653599, -0.3332985605, 0.9999993329})
        a = a * t2 + c;
    a *= t;
    if (steep) a = 1.5707963267948966 - a;
    return x < 0 ? 3.141592653589793 - a : a;
}

/// The integral over a planar emitter with outline @p corners and emitting side @p emitter of
/// cos(receiver) cos(emitter) / d^2, seen from @p p with unit normal @p n: the limit of the sample
/// sum. Lambert's formula, half the sum over the outline's edges of the angle each subtends times
/// the cosine between @p n and the normal of the plane through @p p and the edge, over the outline
/// clipped to the hemisphere above @p p (where the sampled cosine is clamped to 0).
double emitterIntegral(const std::vector<glm::dvec3>& corners, const glm::dvec3& emitter, const glm::dvec3& p, const glm::dvec3& n) {
    if (!(glm::dot(emitter, p - corners[0]) > 0)) return 0.0;  // behind a one-sided emitter
    thread_local std::vector<glm::dvec3> clipped;
    clipped.clear();
    for (size_t i = 0; i < corners.size(); ++i) {  // Sutherland-Hodgman against n . (q - p) >= 0
        const glm::dvec3 a = corners[i] - p, b = corners[(i + 1) % corners.size()] - p;
        const double da = glm::dot(n, a), db = glm::dot(n, b);
        if (da >= 0) clipped.push_back(a);
        if ((da >= 0) != (db >= 0)) clipped.push_back(a + (b - a) * (da / (da - db)));
    }
    // Unit directions to the outline's vertices, each normalized once (zero: a vertex at p).
    for (glm::dvec3& v : clipped) {
        const double l = glm::length(v);
        v = l > 0 ? v / l : glm::dvec3(0.0);
    }
    double sum = 0;
    for (size_t i = 0; i < clipped.size(); ++i) {
        const glm::dvec3 &a = clipped[i], &b = clipped[(i + 1) % clipped.size()];
        if (a == glm::dvec3(0.0) || b == glm::dvec3(0.0)) continue;
        const glm::dvec3 g = glm::cross(a, b);
        const double s = glm::length(g);
        if (s > 0) sum += angleOf(s, glm::dot(a, b)) * glm::dot(n, g) / s;
    }
    return 0.5 * std::abs(sum);
}

}  // namespace

glm::dvec3 ReceiverShader::lightIrradiance(uint32_t r, int li, const uint64_t* groupWords, bool fullUmbra,
                                           uint64_t& blocked, const uint32_t* depth) const {
    const glm::dvec3 p(receivers_.position[r]), n(receivers_.normal[r]);
    const int set = int(sets_[r]);
    const PerLight& light = lights_[li];
    blocked = 0;
    const uint32_t g0 = samples_.lightFirstGroup[li], g1 = samples_.lightFirstGroup[li + 1];
    auto blockedWord = [&](uint32_t k) { return fullUmbra ? samples_.groups[k].fullMask() : (groupWords ? groupWords[k] : 0); };
    // A planar emitter (the common case): the visible samples' terms computed four at a time, the
    // light's weight applied once.
    if (sumsInLanes(light, n) && size_t(light.samples) <= kMaxMaskedSamples) {
        uint64_t visible[kMaxMaskedSamples / 64 + 1];
        std::fill_n(visible, size_t(light.samples + 63) / 64 + 1, 0);  // a group may straddle into the last word
        const uint32_t lightFirst = samples_.groups[g0].first;
        uint64_t anyShown = 0;
        for (uint32_t k = g0; k < g1; ++k) {
            const LightSampleGroup& g = samples_.groups[k];
            const uint64_t word = blockedWord(k);
            blocked += uint64_t(std::popcount(word));
            const uint64_t shown = ~word & g.fullMask();
            anyShown |= shown;
            const uint32_t at = g.first - lightFirst, shift = at & 63u;
            visible[at >> 6] |= shown << shift;
            if (shift && g.count > 64 - shift) visible[(at >> 6) + 1] |= shown >> (64 - shift);
        }
        if (!anyShown) return glm::dvec3(0.0);
        // Through translucent blockers each term takes its sample's transmittance (in sample order).
        return depth ? light.weight * lightTintedSum(r, li, visible, depth) : light.weight * lightSampleSum(r, li, visible);
    }
    glm::dvec3 e(0.0);
    const bool planar = light.planar();
    TransmittanceMemo tint;
    for (uint32_t k = g0; k < g1; ++k) {
        const LightSampleGroup& g = samples_.groups[k];
        const uint64_t word = blockedWord(k);
        blocked += uint64_t(std::popcount(word));
        for (uint64_t visible = ~word & g.fullMask(); visible; visible &= visible - 1) {
            const int sample = int(g.first) + std::countr_zero(visible);
            // Translucent blockers crossed: the sample's weight per channel.
            const glm::dvec3 weight = depth ? light.weight * tint.of(&depth[size_t(sample) * 3]) : light.weight;
            // A sun's sample is a direction (w = 0): the receiver's position does not matter.
            const glm::dvec3 l(samples_.position(set, sample));
            glm::dvec3 d = light.sun ? l : l - p;
            double dist2 = glm::dot(d, d);
            if (!(dist2 > 0)) continue;
            glm::dvec3 w = d / std::sqrt(dist2);
            // A zero normal (volume receivers) means no receiver cosine: fluence-like irradiance.
            double cosReceiver = n == glm::dvec3(0.0) ? 1.0 : std::max(0.0, glm::dot(n, w));
            if (light.sun) {
                e += weight * cosReceiver;
                continue;
            }
            double cosEmitter = planar ? std::max(0.0, -glm::dot(light.normal, w)) : 1.0;
            e += weight * (cosReceiver * cosEmitter / dist2);
        }
    }
    return e;
}

bool ReceiverShader::sumsInLanes(const PerLight& light, const glm::dvec3& n) {
    return !light.sun && light.planar() && n != glm::dvec3(0.0);
}

const double* ReceiverShader::lightSamplesX(uint32_t r, int li) const {
    std::call_once(soaOnce_, [&] {
        const size_t n = samples_.positions.size();
        soa_.resize(3 * n);
        for (size_t i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c) soa_[c * n + i] = samples_.positions[i][c];
    });
    return soa_.data() + size_t(sets_[r]) * samples_.sampleCount + samples_.groups[samples_.lightFirstGroup[li]].first;
}

double ReceiverShader::lightSampleSum(uint32_t r, int li, const uint64_t* visible) const {
    const double* x = lightSamplesX(r, li);
    const size_t total = samples_.positions.size();
    return sampleSum(x, x + total, x + 2 * total, size_t(lights_[li].samples), glm::dvec3(receivers_.position[r]),
                     glm::dvec3(receivers_.normal[r]), lights_[li].normal, visible);
}

glm::dvec3 ReceiverShader::lightTintedSum(uint32_t r, int li, const uint64_t* visible, const uint32_t* depth) const {
    const double* x = lightSamplesX(r, li);
    const size_t total = samples_.positions.size(), n = size_t(lights_[li].samples);
    const glm::dvec3 p(receivers_.position[r]), normal(receivers_.normal[r]);
    const uint32_t* lightDepth = depth + 3 * size_t(samples_.groups[samples_.lightFirstGroup[li]].first);
    return hasAvx2() ? tintedSampleSumAvx2(x, x + total, x + 2 * total, n, p, normal, lights_[li].normal, visible, lightDepth)
                     : tintedSampleSumScalar(x, x + total, x + 2 * total, n, p, normal, lights_[li].normal, visible, lightDepth);
}

glm::dvec3 ReceiverShader::unoccludedIrradiance(uint32_t r, int li) const {
    const PerLight& light = lights_[li];
    const glm::dvec3 p(receivers_.position[r]), n(receivers_.normal[r]);
    if (!light.corners.empty() && n != glm::dvec3(0.0))
        return light.radiance * emitterIntegral(light.corners, light.normal, p, glm::normalize(n));
    if (sumsInLanes(light, n)) return light.weight * lightSampleSum(r, li, nullptr);
    uint64_t none = 0;
    return lightIrradiance(r, li, nullptr, false, none);
}

void ReceiverShader::shade(uint32_t r, const uint64_t* groupWords, bool fullUmbra, ReceiverResults& out,
                           const uint32_t* depth) const {
    const bool perLight = out.lights > 1;
    uint64_t blocked = 0;
    glm::dvec3 total(0.0);
    for (int li = 0; li < samples_.lightCount(); ++li) {
        uint64_t lightBlocked = 0;
        const glm::dvec3 e = lightIrradiance(r, li, groupWords, fullUmbra, lightBlocked, depth);
        blocked += lightBlocked;
        total += e;
        if (perLight) {
            out.lightVisibility[size_t(r) * out.lights + li] = float(1.0 - double(lightBlocked) / lights_[li].samples);
            out.lightIrradiance[size_t(r) * out.lights + li] = glm::vec3(e);
        }
    }
    out.visibility[r] = samples_.sampleCount ? float(1.0 - double(blocked) / samples_.sampleCount) : 1.f;
    out.irradiance[r] = glm::vec3(total);
}

void ReceiverShader::shadeVisibleFraction(uint32_t r, const float* lightVisibility, ReceiverResults& out,
                                          const uint32_t* depth, const uint64_t* tintSamples) const {
    double visible = 0;
    glm::dvec3 total(0.0);
    for (int li = 0; li < samples_.lightCount(); ++li) {
        // A light fully blocked brings nothing: most receivers of a hard-edged preview are there.
        glm::dvec3 e = lightVisibility[li] > 0 ? unoccludedIrradiance(r, li) * double(lightVisibility[li]) : glm::dvec3(0.0);
        if (depth && lightVisibility[li] > 0) {
            uint64_t blocked = 0;
            const glm::dvec3 through = lightIrradiance(r, li, tintSamples, false, blocked, depth),
                             open = lightIrradiance(r, li, tintSamples, false, blocked, nullptr);
            for (int c = 0; c < 3; ++c) e[c] *= open[c] > 0 ? through[c] / open[c] : 1.0;
        }
        visible += double(lightVisibility[li]) * lights_[li].samples;
        total += e;
        if (out.lights > 1) {
            out.lightVisibility[size_t(r) * out.lights + li] = lightVisibility[li];
            out.lightIrradiance[size_t(r) * out.lights + li] = glm::vec3(e);
        }
    }
    out.visibility[r] = samples_.sampleCount ? float(visible / samples_.sampleCount) : 1.f;
    out.irradiance[r] = glm::vec3(total);
}

void shadeEach(size_t count, bool quiet, const std::function<void(size_t)>& shadeOne) {
    ProgressReporter shading("shade", count, quiet);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 1024), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) shadeOne(i);
        shading.update(range.size());
    });
    shading.done();
}

}  // namespace penumbra
