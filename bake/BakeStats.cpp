#include "bake/BakeStats.h"

#include "bake/shading/ReceiverShading.h"
#include "bake/Scene.h"
#include "bake/cast/HardShadowBlock.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Memory.h"

#include <cmath>

namespace penumbra {
namespace {

nlohmann::json table2(const BakeStatsInputs& in) {
    // hpc's cast time is its own wall time of the cast (it includes the replay read); a method
    // without one reports the time its casts took in the pipeline.
    // hpc's pass that finds the receivers closed casters must not skip for is part of its cast.
    const double cast = in.cast.castSeconds > 0 ? in.cast.castSeconds + in.cast.closedExemptSeconds : in.castSeconds;
    return {{"sort_time_s", in.buckets.seconds},
            {"hierarchy_build_time_s", in.cast.hierarchyBuildSeconds},
            {"hierarchy_build_wall_s", in.cast.hierarchyBuildWallSeconds},
            {"penumbra_cast_time_s", cast},
            {"replay_read_time_s", in.cast.replayReadSeconds},
            {"shade_time_s", in.cast.shadeSeconds},
            {"samples_memory_bytes", in.receivers.bytes() + in.cast.receiverBytes},
            {"peak_hierarchy_memory_bytes", in.cast.peakHierarchyBytes},
            {"peak_mask_memory_bytes", in.cast.peakMaskBytes},
            {"total_time_s", in.totalSeconds}};
}

nlohmann::json counters(const BakeStatsInputs& in) {
    const OpenedSolids none;
    const OpenedSolids& opened = in.openedSolids ? *in.openedSolids : none;
    return {{"triangles_read", in.triangles},
            // Culled by the reach tests, whether in the bucket pass (never written) or by the caster.
            {"triangles_culled_at_root", in.cast.trianglesCulledAtRoot + in.buckets.culledTriangles},
            {"triangles_culled_before_spill", in.buckets.culledTriangles},
            {"closed_back_faces_skipped", in.cast.closedBackFaces},
            {"closed_solids_opened", opened.ordinals.size()},
            {"closed_triangles_opened", opened.triangles},
            {"closed_solids_not_watertight", opened.leakySolids()},
            {"closed_solids_crossing", opened.crossingSolids()},
            {"closed_solids_too_large_to_check", opened.uncheckedSolids()},
            {"closed_casters_off_for_scale", opened.castersOffForScale},
            {"closed_exempt_receivers", in.cast.closedExemptReceivers},
            {"closed_exempt_time_s", in.cast.closedExemptSeconds},
            {"rebuilds", in.cast.rebuilds},
            {"peak_live_masks", in.cast.peakLiveMasks},
            {"hard_shadow_tests", in.cast.hardShadowTests},
            {"table_decided_relations", in.cast.tableDecidedRelations},
            {"alpha_tests", in.cast.alphaTests},
            {"alpha_rejected", in.cast.alphaRejected},
            {"alpha_group_tests", in.cast.alphaGroupTests},
            {"alpha_groups_decided", in.cast.alphaGroupsDecided},
            {"sample_table_bytes", in.cast.sampleTableBytes},
            {"peak_rss_bytes", peakRssBytes()}};
}

nlohmann::json bucketStats(const BakeStatsInputs& in) {
    const BucketStats& b = in.buckets;
    const BucketReplaySource* replay = in.replay;
    return {{"files", b.nonEmptyFiles},
            {"bytes_written", b.bytesWritten},
            {"triangles_culled", b.culledTriangles},
            {"bytes_read", replay ? replay->bytesRead() : 0},
            {"bytes_per_triangle", b.bytesPerTriangle()},
            {"write_mb_per_s", b.megabytesPerSecond()},
            {"write_time_s", b.writeSeconds},
            {"read_mb_per_s", replay && replay->readSeconds() > 0 ? double(replay->bytesRead()) / 1e6 / replay->readSeconds() : 0.0},
            {"pass_time_s", b.seconds}};
}

}  // namespace

nlohmann::json bakeStats(const BakeStatsInputs& in) {
    uint64_t blocked = 0;
    auto count = [&](float v) { blocked += uint64_t(std::llround((1.0 - v) * in.samples.sampleCount)); };
    if (in.castShare)
        for (uint32_t r : *in.castShare) count(in.results.visibility[r]);
    else
        for (float v : in.results.visibility) count(v);
    nlohmann::json stats = {
        {"scene", in.scene.file},
        {"method", in.method},
        {"threads", in.threads},
        {"simd", simdName(hardShadowKernels(in.options.simd).level)},
        {"receivers", in.receivers.size()},
        {"light_samples", in.samples.sampleCount},
        {"sample_sets", in.samples.sets},
        {"light_sample_groups", in.samples.groupCount()},
        {"epsilon", {{"relative", in.options.epsilon}, {"length", in.options.epsilonLength}}},
        {"blocked_relations", blocked},
        {"table2", table2(in)},
        {"counters", counters(in)},
        {"memory_plan",
         {{"budget_bytes", in.plan.budget},
          {"tiles", in.plan.tiles},
          {"resident_bytes", in.plan.residentBytes},
          {"per_receiver_bytes", in.plan.perReceiverBytes},
          {"minimum_budget_bytes", in.plan.minimumBudget},
          {"source_bytes", in.demand.sourceBytes},
          {"method_bytes", in.demand.methodBytes}}},
        {"stream", {{"open_time_s", in.openSeconds}, {"scan_time_s", in.streamSeconds}, {"triangles", in.triangles}}},
        {"buckets", bucketStats(in)},
    };
    if (in.refineSeconds > 0) stats["antialias"]["refine_scan_time_s"] = in.refineSeconds;
    return stats;
}

void writeStats(const std::string& path, const nlohmann::json& stats) {
    const std::string text = stats.dump(2) + "\n";
    ensureParentDirectory(path);
    writeFileAtomically(path, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
}

}  // namespace penumbra
