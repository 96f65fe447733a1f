#pragma once
/// @file TranslucentBlockers.h
/// @brief Coloured translucent blockers (issue #15): the per-sample optical depth of a receiver's
/// relations that no opaque blocker blocks.
///
/// A translucent triangle never blocks: methods cast the opaque and cut-out triangles only
/// (translucent ones reach them marked kTriangleNoCast, OpaqueOnlySource), and once a receiver's
/// opaque mask is final the pipeline adds, for each of its unblocked samples, the optical depth
/// (stream/Translucency.h) of every translucent triangle that the blocking rule says the segment
/// crosses (blocksWithAlpha(), so a max_distance or a tie is decided as for an opaque blocker).
/// Integer sums: the result is the same whatever the order of the triangles, the method, the
/// tiles or the threads. Receivers in full umbra do no translucent work; a triangle is skipped
/// for a receiver and a group of point samples only when a bounding-sphere test proves that no
/// segment of the group can reach it, and for the receiver when it lies within eps of the
/// triangle's plane (where the rule blocks nothing).
/// The segments are tested four samples at a time with the hard-shadow kernels the casters use
/// (HardShadowBlock.h: the rule's expressions lane by lane, so the same bits as blocks()). A hard
/// shadow volume depends on the sample and the triangle only, so the blocks of the first
/// triangles, up to kCachedBlockBytes, are built once for every sample set; the rest are built
/// per receiver and group.
/// Memory: the translucent triangles (BlockerTriangle, their bounding spheres and depths) and the
/// cached blocks, held for the bake, and one scratch row of samples x 3 depths per thread.

#include "bake/cast/Caster.h"
#include "bake/cast/HardShadowBlock.h"
#include "bake/light/Light.h"
#include "bake/rule/BlockingRule.h"
#include "stream/AlphaTable.h"
#include "stream/Translucency.h"
#include "stream/TriangleSource.h"

#include <atomic>
#include <memory>
#include <span>
#include <vector>

namespace penumbra {

class TranslucentBlockers {
public:
    /// Hard-shadow blocks built once, at most: 8 MiB (80 KiB a triangle at 256 samples in 4 sets).
    static constexpr uint64_t kCachedBlockBytes = uint64_t(8) << 20;

    TranslucentBlockers() = default;
    /// @brief Reads @p blockers once (then rewinds it) and keeps its translucent triangles that
    /// cast shadows, for the samples @p samples.
    /// @param simd the kernels' instruction set (every level gives the same bits)
    /// @param cacheBytes at most this many bytes of blocks are built once (tests lower it)
    TranslucentBlockers(TriangleSource& blockers, const LightSamples& samples, SimdLevel simd = SimdLevel::Auto,
                        uint64_t cacheBytes = kCachedBlockBytes);
    /// @brief The same from triangles in memory (tests, methods that hold the scene).
    TranslucentBlockers(std::span<const Triangle> triangles, const LightSamples& samples, SimdLevel simd = SimdLevel::Auto,
                        uint64_t cacheBytes = kCachedBlockBytes);

    bool empty() const { return tris_.empty(); }
    size_t size() const { return tris_.size(); }
    /// Triangles whose blocks are built once (the first ones, up to the cache's bytes).
    size_t cachedTriangles() const { return cached_; }
    /// @brief Bytes held for the bake (the memory plan's part for translucency).
    size_t bytes() const;
    /// @brief Bytes held for @p triangles translucent triangles and @p groups sample groups
    /// (before they are read), without the cached blocks: those take only what the plan leaves spare.
    static uint64_t bytesFor(uint64_t triangles, size_t groups);

    /// @brief Receiver @p r's per-sample depth: @p depth (sampleCount x 3, sample-major) gets, for
    /// each sample not set in @p groupWords, the saturating sum of the depths of the translucent
    /// triangles its segment crosses, and 0 for blocked samples.
    /// @param groupWords the receiver's opaque mask, one word per group (nullptr: none blocked)
    /// @param fullUmbra every sample blocked
    /// @return whether any depth is not 0 (else the receiver is shaded as without translucency)
    bool depthAt(const glm::dvec3& r, int set, const uint64_t* groupWords, bool fullUmbra, const ReceiverEpsilon& epsilon,
                 const AlphaTable& alpha, std::span<uint32_t> depth) const;

    /// Relations tested against a translucent triangle, and crossings found, for the stats.
    mutable std::atomic<uint64_t> tests{0}, crossings{0};

private:
    void add(const Triangle& t);
    void prepare(SimdLevel simd, uint64_t cacheBytes);
    /// Triangle @p i's blocks of group @p k in set @p set: the cached ones, or those of the
    /// samples in @p open built into @p scratch. @p which gets the blocks holding them.
    const HardShadowBlock* blocksOf(size_t i, int set, size_t k, uint64_t open, HardShadowBlock* scratch, uint32_t& which) const;

    struct Sphere {
        glm::dvec3 centre{0.0};
        double radius = 0.0;
    };
    const LightSamples* samples_ = nullptr;
    std::vector<BlockerTriangle> tris_;
    std::vector<Sphere> spheres_;      ///< per triangle
    std::vector<OpticalDepth> depths_; ///< per triangle
    std::vector<Sphere> groups_;       ///< per sample group, over all sets (point samples only)
    HardShadowKernels kernels_;
    std::vector<uint32_t> blockFirst_;      ///< group k's first block within a set
    size_t blocksPerSet_ = 0, cached_ = 0;  ///< blocks of one triangle and set; triangles cached
    std::vector<HardShadowBlock> cache_;    ///< [triangle < cached_][set][block]
};

/// @brief A non-owning view of @p inner in which translucent triangles carry kTriangleNoCast:
/// what a method casts (the receiver kind's passes still see them; no method blocks with them).
/// It also keeps a copy of every translucent triangle of its first full pass, so a bake needs no
/// read of its own to find them: every method reads the whole replay before it reports a receiver.
class OpaqueOnlySource final : public TriangleSource {
public:
    /// @param markNoCast false for a method that casts translucent triangles itself: they are
    /// collected but reach it unmarked.
    OpaqueOnlySource(TriangleSource& inner, bool markNoCast) : inner_(inner), mark_(markNoCast ? kTriangleNoCast : 0u) {}
    size_t read(std::span<Triangle> out) override;
    void rewind() override { inner_.rewind(), position_ = 0; }
    /// Skipped triangles are not collected: sharded bakes refuse translucent scenes (Pipeline.cpp).
    uint64_t skip(uint64_t count) override;
    std::string name() const override { return inner_.name(); }
    std::optional<uint64_t> sizeHint() const override { return inner_.sizeHint(); }
    std::optional<uint64_t> knownSize() const override { return inner_.knownSize(); }
    uint64_t residentBytes() const override { return inner_.residentBytes(); }
    uint32_t part() const override { return inner_.part(); }
    std::vector<uint64_t> costRuns() const override { return inner_.costRuns(); }

    /// True once a read reached the end of the stream: translucent() holds them all.
    bool complete() const { return complete_; }
    /// The translucent triangles seen, in replay order.
    const std::vector<Triangle>& translucent() const { return translucent_; }

private:
    TriangleSource& inner_;
    std::vector<Triangle> translucent_;
    uint64_t position_ = 0, collectedUpTo_ = 0;  ///< replay position; triangles looked at so far
    uint32_t mark_;
    bool complete_ = false;
};

/// @brief What a bake casts translucent blockers with, once @p view has read the whole replay:
/// null when it held none or when method @p method weighs them itself (traits.translucency).
/// @param partialFiles the flag of a sharded or checkpointed bake ("--shard", "--checkpoint"), or null
/// @param cacheBytes at most this many bytes of blocks are built once (TranslucentBlockers())
/// @throw InputError for partial files (they do not carry depths)
/// @throw std::logic_error when the method reported a receiver before reading every blocker
std::unique_ptr<TranslucentBlockers> translucentPass(const OpaqueOnlySource& view, const LightSamples& samples,
                                                     const std::string& method, const CasterTraits& traits,
                                                     const char* partialFiles, SimdLevel simd, uint64_t cacheBytes);

/// @brief A mask (one word per group, LightSampleGroup layout) with every sample set but
/// @p perLight of each light's (or all it has), spread over the light by farthest-point
/// selection: the samples of a preview's tint.
std::vector<uint64_t> samplesOutsideSubset(const LightSamples& samples, int perLight);

}  // namespace penumbra
