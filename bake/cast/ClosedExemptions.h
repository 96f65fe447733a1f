#pragma once
/// @file ClosedExemptions.h
/// @brief The receivers for which closed casters (Sintorn et al. 2008) could lose a shadow, found
/// before the cast so that they are cast with every face.
///
/// Closed casters skip a closed face E for a receiver r when r lies in front of E (E faces away
/// from the whole light, or r is more than eps(r) in front of it): a segment from r that enters
/// the solid S through E must leave S through a face G that faces the light, and G blocks it.
/// That fails in one case: G does not block under the rule because r lies within eps(r) *behind*
/// G's plane (BlockingRule.h), outside S (beside it, on the extension of G's plane). The reference
/// then counts E, which closed casters skipped (docs/performance.md, "Closed casters").
///
/// So before a tile is cast, one pass over the closed faces marks every receiver r for which some
/// closed face G that does not face away from a light has
///  - r behind G's plane by more than p (two float ulps of its coordinates) and at most eps(r) + m,
///  - r inside V_L of G for that light (a segment from r to the light may cross G), and
///  - r *not* inside G's prism by more than m (its projection on G's plane is outside G, or
///    within m of its edges), and
///  - the segment from r to one of its own samples of that light (its sample set's) crosses G
///    from behind, up to a relative 1e-9 on G's edges.
/// A marked receiver is also cast against the closed faces alone with closed casters off, and its
/// masks are the OR of both casts: every face's bits, as the reference finds them.
///
/// A receiver on G's plane up to p (a camera pixel on the coplanar face of the next box in a row,
/// whose float hit point lies a few ulps off the plane) is not marked: a segment from it that
/// leaves through G runs within p of G's plane all the way, so it enters the solid within p of
/// G's edge, and that relation is a tie of the entry face's edge, whose tolerance holds 4 float
/// ulps of the coordinates (bake/rule/TieClassifier.h). Marking such receivers cost more than
/// closed casters save on rows of coplanar boxes (stop 55's sweep: 27 s of a 31 s bake).
///
/// The third condition keeps receivers that lie *on* a light-facing face (a camera pixel on a box's
/// top, with receiver_offset 0) unmarked, which is most receivers on closed solids. Let r lie in
/// G's prism, within eps(r) behind G's plane, and outside S. The segment's path from r to where it
/// leaves through G stays in the prism (G is convex) at depth below eps(r), so it enters S under
/// G's interior. Where a face E of S meets G at an edge, r (inside the prism) lies nearer to E's
/// plane than to G's, within eps(r), and E does not block either, in the reference too. Otherwise
/// S is thinner than eps(r) under G (a sheet whose other face lies within the rule's band), which
/// is outside the exactness argument (docs/performance.md, "Closed casters").
///
/// Marks are decided per receiver by point tests alone (the index's box tests are conservative
/// for the same arithmetic), so they do not depend on the tiles or on the thread count.
///
/// Memory: the ids of the receivers searched, a bounding-volume hierarchy over them (about 4 bytes
/// per receiver) and one flag byte per receiver, freed before the tile's cast.

#include "bake/cast/BlockerBatch.h"
#include "bake/cast/CastOptions.h"
#include "bake/cast/PenumbraVolume.h"
#include "bake/light/Light.h"
#include "bake/rule/BlockingRule.h"
#include "receivers/ReceiverSet.h"
#include "stream/TriangleSource.h"

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

namespace penumbra {

/// @brief Blockers per chunk that the caster of the marked receivers prepares at once (HpcCaster
/// feeds it the closed faces in pieces this small), so its ring stays small.
inline constexpr size_t kClosedExemptChunk = 512;

/// @brief Memory of that caster's ring of prepared chunks, for the memory plan.
inline size_t closedExemptCasterBytes(size_t lights) { return 2 * BlockerBatch::bytes(kClosedExemptChunk, lights); }

/// @brief How far a receiver may lie on the wrong side of a closed face's plane, or inside its
/// prism, and still be marked: 1e-12 of the scale of r and of G's first vertex, far above the
/// rounding of a plane's evaluation (about 1e-16 of it).
/// @param extent |r|_inf (or the largest of a box of receivers)
/// @param vertex |v0|_inf of the face
inline double closedExemptionMargin(double extent, double vertex) { return 4e-12 * (extent + vertex); }

/// @brief How far behind a closed face's plane a receiver must lie to be marked: two float ulps
/// (2^-23) of the larger of its coordinates and the face's first vertex, half of the coordinates'
/// share of the tie classifier's tolerances.
inline double closedOnPlaneBand(double extent, double vertex) { return 0x1p-23 * std::max(extent, vertex); }

/// @brief Whether closed face @p g (its V_L @p volume for one light) could be the face that fails
/// to block a segment from @p r that entered its solid elsewhere: the four conditions above.
/// @param samples the receiver's samples of that light (its sample set's), of weight @p w
bool closedFaceMayFailAt(const BlockerTriangle& g, const PenumbraVolume& volume, const glm::dvec3& r,
                         const ReceiverEpsilon& epsilon, std::span<const glm::vec3> samples, double w);

/// @brief Marks receivers over chunks of blockers. Thread-safe per chunk (scan() runs the
/// chunk's faces in parallel); feed every chunk of the replay, then take exempt().
class ClosedExemptionFinder {
public:
    /// @param ids the receivers to search (sorted or not; exempt() is sorted)
    /// @param sampleSets the sample set of every receiver of @p receivers
    ClosedExemptionFinder(const LightSamples& samples, const ReceiverSet& receivers, std::span<const uint32_t> sampleSets,
                          std::span<const uint32_t> ids, const CastOptions& options);
    ~ClosedExemptionFinder();

    /// @brief Tests every closed, opaque face of @p blockers against the receivers.
    void scan(std::span<const Triangle> blockers);
    /// @brief The marked receivers, sorted.
    std::vector<uint32_t> exempt() const;
    /// @brief Closed faces tested (against at least one light) so far.
    uint64_t facesTested() const { return facesTested_.load(); }

private:
    struct Index;  // the bounding-volume hierarchy over the ids (ClosedExemptions.cpp)
    void scanFace(const Triangle& t);

    /// The receiver's samples of light @p l.
    std::span<const glm::vec3> samplesOf(uint32_t receiver, size_t l) const;

    const LightSamples& samples_;
    const ReceiverSet& receivers_;
    std::span<const uint32_t> sampleSets_;
    ReceiverEpsilon epsilon_;
    SimdLevel level_;  ///< which code builds V_L and tests boxes against it
    std::vector<std::pair<uint32_t, uint32_t>> lightSamples_;  ///< per light: its first sample and count
    std::unique_ptr<Index> index_;
    Box root_;  ///< the index's root box: V_L is abandoned once it leaves it outside
    std::unique_ptr<std::atomic<uint8_t>[]> marked_;  ///< per position in the index's ids
    std::atomic<uint64_t> facesTested_{0};
};

/// @brief Reads @p blockers from where they are to their end and returns the receivers of @p ids
/// that closed casters must not skip for (sorted). Checks for a stop request between chunks.
/// @param facesTested when given, receives the closed faces tested
std::vector<uint32_t> findClosedExemptions(TriangleSource& blockers, const LightSamples& samples,
                                           const ReceiverSet& receivers, std::span<const uint32_t> sampleSets,
                                           std::span<const uint32_t> ids, const CastOptions& options,
                                           uint64_t* facesTested = nullptr);

}  // namespace penumbra
