#pragma once
// Shared helpers for the [procedural] tests: open a generator from JSON the way the scene loader
// does, hash a whole stream, check determinism across thread counts and chunk sizes, and
// summarise geometry (finite, degenerate, bounds).

#include "procedural/Generators.h"
#include "stream/util/Error.h"
#include "stream/SourceRegistry.h"
#include "stream/TriangleSource.h"

#include <catch2/catch.hpp>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <limits>
#include <string>
#include <vector>

namespace penumbra::test {

/// Opens a geometry entry ({"type": ..., params...}) as geometry[0] of "scene.json".
inline TriangleSourcePtr openEntry(const nlohmann::json& entry, const std::string& baseDir = ".") {
    registerProceduralGenerators();
    nlohmann::json params = entry;
    std::string type = params.at("type");
    params.erase("type");
    return openSource(type, SourceRequest{params, "scene.json", "geometry[0]", baseDir});
}

/// FNV-1a over the bytes of every triangle, read in chunks of @p chunk (the result does not
/// depend on the chunking, which is the point of reading with odd sizes).
inline uint64_t streamHash(TriangleSource& source, size_t chunk = kTriangleChunk) {
    source.rewind();
    std::vector<Triangle> buffer(chunk);
    uint64_t hash = 14695981039346656037ull;  // 64-bit FNV-1a
    while (size_t n = source.read(buffer)) {
        const auto* bytes = reinterpret_cast<const unsigned char*>(buffer.data());
        for (size_t i = 0; i < n * sizeof(Triangle); ++i) hash = (hash ^ bytes[i]) * 1099511628211ull;
    }
    return hash;
}

/// Hash of a freshly opened source with TBB limited to @p threads.
inline uint64_t hashWithThreads(const nlohmann::json& entry, int threads, size_t chunk = kTriangleChunk) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
    TriangleSourcePtr source = openEntry(entry);
    return streamHash(*source, chunk);
}

/// The same stream for 1 and 2 threads, for a second opening, after a rewind, and for odd chunk sizes.
inline void requireDeterministic(const nlohmann::json& entry) {
    INFO(entry.dump());
    const uint64_t one = hashWithThreads(entry, 1);
    CHECK(hashWithThreads(entry, 2) == one);
    CHECK(hashWithThreads(entry, 2) == one);
    CHECK(hashWithThreads(entry, 2, 97) == one);
    CHECK(hashWithThreads(entry, 1, 4099) == one);
    TriangleSourcePtr source = openEntry(entry);
    CHECK(streamHash(*source, 1000) == one);
    CHECK(streamHash(*source, 1000) == one);  // streamHash rewinds first
}

struct StreamSummary {
    uint64_t count = 0, nonFinite = 0, degenerate = 0, flagged = 0;
    glm::dvec3 lo{std::numeric_limits<double>::max()}, hi{-std::numeric_limits<double>::max()};
    std::vector<Triangle> triangles;  ///< kept when asked (small streams only)
};

/// Reads @p source once: counts, non-finite and zero-area triangles, alpha-matte flags, bounds.
inline StreamSummary summarise(TriangleSource& source, bool keep = false) {
    StreamSummary s;
    source.rewind();
    std::vector<Triangle> buffer(kTriangleChunk);
    while (size_t n = source.read(buffer)) {
        for (size_t i = 0; i < n; ++i) {
            const Triangle& t = buffer[i];
            ++s.count;
            if (!isFinite(t)) ++s.nonFinite;
            const glm::dvec3 a(t.v[0]), b(t.v[1]), c(t.v[2]);
            if (glm::length(glm::cross(b - a, c - a)) == 0.0) ++s.degenerate;
            if (t.flags & kTriangleAlphaMatte) ++s.flagged;
            for (const glm::vec3& p : t.v) s.lo = glm::min(s.lo, glm::dvec3(p)), s.hi = glm::max(s.hi, glm::dvec3(p));
        }
        if (keep) s.triangles.insert(s.triangles.end(), buffer.begin(), buffer.begin() + ptrdiff_t(n));
    }
    source.rewind();
    return s;
}

/// Opening @p entry throws InputError whose message contains @p fragment.
inline void requireInputError(const nlohmann::json& entry, const std::string& fragment) {
    INFO(entry.dump());
    CHECK_THROWS_AS(openEntry(entry), InputError);
    CHECK_THROWS_WITH(openEntry(entry), Catch::Contains(fragment));
}

}  // namespace penumbra::test
