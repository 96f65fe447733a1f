#include "bake/cast/Caster.h"

#include "stream/util/Error.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <map>
#include <mutex>

namespace penumbra {
namespace {

/// The registry lives in a function so that registrations from any translation unit's static
/// initializers find it constructed.
struct Registry {
    std::mutex mutex;
    std::vector<std::unique_ptr<CasterEntry>> entries;  ///< stable addresses for casterEntry()
};

Registry& registry() {
    static Registry r;
    return r;
}

/// Listing order: the exact methods people compare first, then the rest alphabetically.
int rank(const std::string& name) {
    static const std::vector<std::string> first = {"hpc", "reference", "embree"};
    auto it = std::find(first.begin(), first.end(), name);
    return it == first.end() ? int(first.size()) : int(it - first.begin());
}

}  // namespace

void addSequential(CastStats& total, const CastStats& s) {
    total.hierarchyBuildSeconds += s.hierarchyBuildSeconds;
    total.hierarchyBuildWallSeconds += s.hierarchyBuildWallSeconds;
    total.castSeconds += s.castSeconds;
    total.replayReadSeconds += s.replayReadSeconds;
    total.shadeSeconds += s.shadeSeconds;
    total.trianglesProcessed += s.trianglesProcessed;
    total.trianglesCulledAtRoot += s.trianglesCulledAtRoot;
    total.closedBackFaces += s.closedBackFaces;
    total.closedExemptReceivers += s.closedExemptReceivers;
    total.closedExemptSeconds += s.closedExemptSeconds;
    total.rebuilds += s.rebuilds;
    total.hardShadowTests += s.hardShadowTests;
    total.tableDecidedRelations += s.tableDecidedRelations;
    total.alphaTests += s.alphaTests;
    total.alphaRejected += s.alphaRejected;
    total.alphaGroupTests += s.alphaGroupTests;
    total.alphaGroupsDecided += s.alphaGroupsDecided;
    total.sampleTableBytes = std::max(total.sampleTableBytes, s.sampleTableBytes);
    total.peakLiveMasks = std::max(total.peakLiveMasks, s.peakLiveMasks);
    total.peakMaskBytes = std::max(total.peakMaskBytes, s.peakMaskBytes);
    total.peakHierarchyBytes = std::max(total.peakHierarchyBytes, s.peakHierarchyBytes);
    total.receiverBytes = std::max(total.receiverBytes, s.receiverBytes);
}

CasterRegistration::CasterRegistration(CasterEntry entry) {
    Registry& r = registry();
    std::lock_guard lock(r.mutex);
    r.entries.push_back(std::make_unique<CasterEntry>(std::move(entry)));
    std::sort(r.entries.begin(), r.entries.end(), [](const auto& a, const auto& b) {
        return rank(a->name) != rank(b->name) ? rank(a->name) < rank(b->name) : a->name < b->name;
    });
}

std::vector<std::string> casterNames() {
    Registry& r = registry();
    std::lock_guard lock(r.mutex);
    std::vector<std::string> names;
    for (const auto& e : r.entries) names.push_back(e->name);
    return names;
}

void refuseMaxDistance(const CastContext& context, const std::string& method) {
    if (!alphaTableOf(context.options).hasDistances()) return;
    // The exact methods apply it (each tests the rule's own hit distance); name them as built.
    std::vector<std::string> exact;
    for (const std::string& name : casterNames())
        if (casterEntry(name).traits.exact) exact.push_back(name);
    std::string list;
    for (size_t i = 0; i < exact.size(); ++i) list += (i == 0 ? "" : i + 1 == exact.size() ? " or " : ", ") + exact[i];
    fail("--method " + method, "does not apply \"max_distance\" of geometry entries (use {})", list);
}

const CasterEntry& casterEntry(const std::string& name) {
    Registry& r = registry();
    {
        std::lock_guard lock(r.mutex);
        for (const auto& e : r.entries)
            if (e->name == name) return *e;
    }
    std::string known;
    for (const std::string& n : casterNames()) known += (known.empty() ? "" : ", ") + n;
    throw InputError(fmt::format("--method: unknown method \"{}\" (known: {})", name, known));
}

void reportInParallel(uint32_t first, uint32_t end, const std::function<void(uint32_t)>& report) {
    tbb::parallel_for(tbb::blocked_range<uint32_t>(first, end, 1024), [&](const tbb::blocked_range<uint32_t>& range) {
        for (uint32_t r = range.begin(); r != range.end(); ++r) report(r);
    });
}

}  // namespace penumbra
