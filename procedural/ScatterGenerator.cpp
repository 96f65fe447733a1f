#include "procedural/ScatterGenerator.h"

#include "procedural/IndexedSource.h"
#include "stream/util/CheckedMath.h"
#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"
#include "stream/util/Random.h"
#include "stream/Transform.h"

#include <fmt/format.h>

#include <cmath>

namespace penumbra {
namespace {

constexpr double kDegree = 3.14159265358979323846 / 180.0;

/// Where instance k goes: p' = base + Ry(yaw) (scale p), with the source's origin on the ground.
struct Placer {
    ScatterParams p;

    struct Instance {
        glm::dvec3 base;
        double c, s, scale;
    };

    Instance instance(uint64_t k) const {
        Rng rng(hashIndex(p.seed, k));
        double x, z;
        randomPoint(p.placement.area, rng, x, z);
        const double yaw = rng.uniform(p.rotationDeg.x, p.rotationDeg.y) * kDegree;
        return {glm::dvec3(x, p.placement.groundHeight(x, z), z), std::cos(yaw), std::sin(yaw), rng.uniform(p.scale.x, p.scale.y)};
    }

    static void place(const Instance& in, const Triangle& local, Triangle& out) {
        for (int j = 0; j < 3; ++j) {
            const glm::dvec3 q = in.scale * glm::dvec3(local.v[j]);
            out.v[j] = glm::vec3(in.base + glm::dvec3(in.c * q.x + in.s * q.z, q.y, in.c * q.z - in.s * q.x));
        }
        out.flags = local.flags;
    }
};

/// A source small enough to keep: instances are filled in parallel from the copy. The copy is
/// made on the first read, not when the scene opens: the memory plan counts it in between
/// (residentBytes()), so a budget too small for it is refused before it is allocated (two
/// scatters caching 10M triangles peaked at 668 MiB under an 80M budget).
class CachedScatter final : public IndexedSource {
public:
    CachedScatter(const ScatterParams& p, TriangleSourcePtr source, uint64_t per)
        : IndexedSource("scatter", p.placement.count * per), placer_{p}, source_(std::move(source)), per_(per) {}

    size_t read(std::span<Triangle> out) override {
        if (source_) keepSource();
        placer_.p.placement.prepare();
        return IndexedSource::read(out);
    }
    uint64_t residentBytes() const override {
        return per_ * sizeof(Triangle) + (source_ ? source_->residentBytes() : 0) + placer_.p.placement.residentBytes();
    }
    std::string residentDetail() const override {
        if (per_ * sizeof(Triangle) < kNotableResidentBytes) return {};
        return fmt::format("scatter keeps its source's {} triangles ({:.1f} MiB; a smaller cache_triangles streams it instead)",
                           per_, double(per_ * sizeof(Triangle)) / (1 << 20));
    }

protected:
    void triangle(uint64_t index, Triangle& out) const override { fill(index, std::span<Triangle>(&out, 1)); }

    void fill(uint64_t first, std::span<Triangle> out) const override {
        const uint64_t per = local_.size();
        uint64_t current = UINT64_MAX;
        Placer::Instance in{};
        for (size_t k = 0; k < out.size(); ++k) {
            const uint64_t i = (first + k) / per;
            if (i != current) in = placer_.instance(i), current = i;
            Placer::place(in, local_[(first + k) % per], out[k]);
        }
    }

private:
    /// Reads the source into local_ and closes it.
    void keepSource() {
        local_.reserve(size_t(per_));
        std::vector<Triangle> chunk(kTriangleChunk);
        source_->rewind();
        while (size_t n = source_->read(chunk)) {
            if (local_.size() + n > per_) break;
            local_.insert(local_.end(), chunk.begin(), chunk.begin() + ptrdiff_t(n));
        }
        if (local_.size() != per_)
            fail(source_->name(), "source gave {} triangles when kept, {} when counted", local_.size(), per_);
        source_.reset();
    }

    Placer placer_;
    TriangleSourcePtr source_;  // until the first read copies it into local_
    uint64_t per_;
    std::vector<Triangle> local_;
};

/// A source too large to keep: replayed from its start for every instance.
class StreamedScatter final : public TriangleSource {
public:
    StreamedScatter(const ScatterParams& p, TriangleSourcePtr inner, uint64_t per)
        : placer_{p}, inner_(std::move(inner)), per_(per) {}

    size_t read(std::span<Triangle> out) override {
        if (out.empty()) return 0;  // an empty read must not look like the end of an instance
        placer_.p.placement.prepare();
        while (instance_ < placer_.p.placement.count) {
            if (done_ == 0) current_ = placer_.instance(instance_);
            size_t n = inner_->read(out.first(size_t(std::min<uint64_t>(out.size(), per_ - done_))));
            if (n == 0) {
                if (done_ != per_) fail(inner_->name(), "source gave {} triangles on a later pass, {} on the first", done_, per_);
                ++instance_, done_ = 0;
                inner_->rewind();
                continue;
            }
            for (size_t i = 0; i < n; ++i) Placer::place(current_, out[i], out[i]);
            done_ += n;
            if (done_ == per_) {  // next instance starts on the next call, from a rewound source
                ++instance_, done_ = 0;
                inner_->rewind();
            }
            return n;
        }
        return 0;
    }

    void rewind() override {
        inner_->rewind();
        instance_ = done_ = 0;
    }
    /// Whole instances are passed over without touching the source; within one, the source skips.
    uint64_t skip(uint64_t count) override {
        uint64_t skipped = 0;
        while (skipped < count && instance_ < placer_.p.placement.count) {
            if (done_ == 0 && count - skipped >= per_) {  // the source stays rewound
                ++instance_, skipped += per_;
                continue;
            }
            if (done_ == 0) current_ = placer_.instance(instance_);
            const uint64_t want = std::min(count - skipped, per_ - done_);
            if (inner_->skip(want) != want) fail(inner_->name(), "source ended early on a later pass (instance {})", instance_);
            skipped += want, done_ += want;
            if (done_ == per_) ++instance_, done_ = 0, inner_->rewind();
        }
        return skipped;
    }
    std::string name() const override { return "scatter"; }
    std::optional<uint64_t> sizeHint() const override { return placer_.p.placement.count * per_; }
    uint64_t residentBytes() const override { return inner_->residentBytes() + placer_.p.placement.residentBytes(); }
    std::string residentDetail() const override { return inner_->residentDetail(); }

private:
    Placer placer_;
    TriangleSourcePtr inner_;
    uint64_t per_, instance_ = 0, done_ = 0;
    Placer::Instance current_{};
};

}  // namespace

TriangleSourcePtr makeScatterSource(const ScatterParams& params, TriangleSourcePtr source, const std::string& where) {
    // The source's size: its hint, or one pass that counts without keeping anything (a kept
    // source is copied on the first read, once the memory plan has counted it).
    uint64_t per = 0;
    if (const std::optional<uint64_t> hint = source->sizeHint()) {
        per = *hint;
    } else {
        std::vector<Triangle> chunk(kTriangleChunk);
        source->rewind();
        while (size_t n = source->read(chunk)) per += n;
    }
    source->rewind();
    if (per > 0 && params.placement.count > kMaxSceneTriangles / per)
        fail(where, "{} instances of {} triangles are more than the limit of {} triangles (count)", params.placement.count,
             per, kMaxSceneTriangles);
    if (per <= params.cacheTriangles) return std::make_unique<CachedScatter>(params, std::move(source), per);
    return std::make_unique<StreamedScatter>(params, std::move(source), per);
}

TriangleSourcePtr openScatterSource(const SourceRequest& request) {
    // Each level opens the next one recursively: bound the depth before the stack does.
    static thread_local int depth = 0;
    if (depth >= kMaxScatterNesting)
        fail(request.where(), "scatter sources nest more than {} deep", kMaxScatterNesting);
    struct Level {
        Level() { ++depth; }
        ~Level() { --depth; }
    } level;
    JsonParams j(request.params, request.file, request.path);
    ScatterParams p;
    p.placement = parsePlacement(j, 100, kMaxSceneTriangles);
    p.scale = j.range("scale", p.scale);
    p.rotationDeg = j.range("rotation_deg", p.rotationDeg);
    p.cacheTriangles = uint64_t(j.integer("cache_triangles", int64_t(p.cacheTriangles), 0, int64_t(1) << 26));
    p.seed = j.seed("seed", p.seed);
    const nlohmann::json* inline_ = j.raw("source");
    if (!inline_) fail(j.where("source"), "missing required field (a geometry entry such as {{\"type\": \"obj\", \"path\": \"rock.obj\"}})");
    j.finish();
    if (!(p.scale.x > 0 && p.scale.y <= 1e6)) fail(j.where("scale"), "must lie in (0, 1e6], got [{}, {}]", p.scale.x, p.scale.y);
    if (!(std::abs(p.rotationDeg.x) <= 3600 && std::abs(p.rotationDeg.y) <= 3600))
        fail(j.where("rotation_deg"), "must lie in [-3600, 3600], got [{}, {}]", p.rotationDeg.x, p.rotationDeg.y);

    JsonParams s(*inline_, j.file(), j.path("source"));
    // Keys the scene reads on its top-level entries (bake/Scene.cpp), which a source opened here
    // would call unknown although the documentation lists them.
    for (const char* key : {"closed", "cast_shadows", "receive_shadows", "receiver_offset", "max_distance", "translucent"})
        if (s.raw(key)) fail(s.where(key), "is an object control of top-level entries: give it on the scatter entry, where it applies to every instance");
    for (const char* key : {"leaf_texture", "petal_texture", "alpha_cutoff"})
        if (s.raw(key)) fail(s.where(key), "is read on top-level tree, forest and flowers entries only, not inside a scatter's source (a forest or flowers entry places its own instances)");
    const std::string type = s.string("type");
    const Transform transform = parseTransform(s);
    nlohmann::json params = *inline_;
    params.erase("type");
    params.erase("transform");
    TriangleSourcePtr source = openSource(type, SourceRequest{params, request.file, j.path("source"), request.baseDir});
    if (!transform.isIdentity()) source = std::make_unique<TransformedSource>(std::move(source), transform.matrix());
    return makeScatterSource(p, std::move(source), request.where());
}

}  // namespace penumbra
