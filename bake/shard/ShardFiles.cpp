#include "bake/shard/ShardFiles.h"

#include "stream/util/Error.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <filesystem>
#include <functional>
#include <map>

namespace penumbra {
namespace fs = std::filesystem;

namespace {

bool isShardFile(const fs::directory_entry& e, std::error_code& ec) {
    return e.path().extension() == ".pnpart" && e.path().filename().string().starts_with("shard") && e.is_regular_file(ec);
}

/// The shard files of @p dir, by name: every regular `shard*.pnpart` file.
std::vector<std::string> shardFilesOf(const std::string& dir) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) fail(dir, "not a directory of shard files");
    std::vector<std::string> files;
    for (const fs::directory_entry& e : fs::directory_iterator(dir, ec))
        if (isShardFile(e, ec)) files.push_back(e.path().string());
    if (ec) fail(dir, "cannot list the shard directory: {}", ec.message());
    if (files.empty()) fail(dir, "no shard files (shard-I-of-N.pnpart); bake them with --shard I/N --shard-dir {}", dir);
    std::sort(files.begin(), files.end());
    return files;
}

/// What every shard file of one bake shares, and what it is checked against.
struct Expected {
    uint64_t sceneHash = 0, contentHash = 0, receivers = 0;
    uint32_t groups = 0;
    std::function<uint64_t(const PartialHeader&)> settingsHash;
    std::string against;  ///< "this one" (a merge's scene) or the first file's path (a combine)
};

/// Refuses @p f unless it is a shard file of the bake @p e describes, cut like @p first.
void checkShard(const PartialFile& f, const PartialHeader& first, const std::string& firstPath, const Expected& e) {
    const PartialHeader& h = f.header;
    if (h.role != PartialHeader::kShard) fail(f.path, "a checkpoint, not a shard file");
    if (h.sceneHash != e.sceneHash)
        fail(f.path, "shard of another scene file (scene hash {:016x}, {} {:016x})", h.sceneHash, e.against, e.sceneHash);
    if (h.parts != first.parts) fail(f.path, "shard {} of {}, but {} is of {}", h.part, h.parts, firstPath, first.parts);
    if (h.cut != first.cut)
        fail(f.path, "cut by {}, but {} is cut by {}", shardCutName(ShardCut(h.cut)), firstPath, shardCutName(ShardCut(first.cut)));
    if (h.settingsHash != e.settingsHash(h)) fail(f.path, "shard baked with other settings (--method or its options)");
    if (h.contentHash != e.contentHash || h.receivers != e.receivers || h.groups != e.groups ||
        h.lightFirstGroup != first.lightFirstGroup)
        fail(f.path, "shard of other receivers or light samples ({} receivers, {} groups; {} has {} and {})", h.receivers,
             h.groups, e.against, e.receivers, e.groups);
}

/// The shards the files seen so far cover; a second file for a shard is refused.
class Coverage {
public:
    void add(const PartialHeader& h, const std::string& path) {
        auto next = covered_.upper_bound(h.part);
        if (next != covered_.begin() && std::prev(next)->second.end > h.part) overlap(h, path, std::prev(next)->second);
        if (next != covered_.end() && next->first < h.partEnd) overlap(h, path, next->second);
        covered_.emplace(h.part, Covered{h.partEnd, path});
    }
    /// The shards of @p within that no file covers.
    std::vector<uint32_t> missing(ShardRange within) const {
        std::vector<uint32_t> out;
        uint32_t at = within.first;
        for (const auto& [first, c] : covered_) {
            for (; at < std::min(first, within.end); ++at) out.push_back(at);
            at = std::max(at, c.end);
        }
        for (; at < within.end; ++at) out.push_back(at);
        return out;
    }
    ShardRange span() const {
        if (covered_.empty()) return {};
        return {covered_.begin()->first, std::prev(covered_.end())->second.end};
    }

private:
    struct Covered {
        uint32_t end;
        std::string path;
    };
    [[noreturn]] static void overlap(const PartialHeader& h, const std::string& path, const Covered& other) {
        if (h.partEnd == h.part + 1) fail(path, "duplicate of shard {} of {} (also in {})", h.part, h.parts, other.path);
        fail(path, "shards {}-{} of {} overlap those of {}", h.part, h.partEnd - 1, h.parts, other.path);
    }
    std::map<uint32_t, Covered> covered_;  ///< by first shard
};

/// Refuses a set of files that leaves shards of @p within uncovered.
void requireCovered(const Coverage& coverage, ShardRange within, uint32_t parts, const std::string& where) {
    const std::vector<uint32_t> missing = coverage.missing(within);
    if (missing.empty()) return;
    std::string list;
    for (size_t i = 0; i < std::min<size_t>(missing.size(), 8); ++i) list += (i ? ", " : "") + std::to_string(missing[i]);
    fail(where, "missing {} of {} shards ({}{}); rerun them with --shard I/{}", missing.size(), within.end - within.first,
         list, missing.size() > 8 ? ", ..." : "", parts);
}

/// By blockers every shard casts every receiver: a file without one was cut differently.
void requireEveryReceiver(const PartialFile& f) {
    const auto absent = std::find(f.state.begin(), f.state.end(), uint8_t(ReceiverState::Absent));
    if (absent != f.state.end())
        fail(f.path, "receiver {} is missing from a by-blockers shard: the shards were cut differently", absent - f.state.begin());
}

/// By receivers every receiver is cast by exactly one shard.
void requireOncePerReceiver(const std::vector<uint8_t>& covered, const std::string& where) {
    for (size_t r = 0; r < covered.size(); ++r)
        if (covered[r] != 1) fail(where, "receiver {} is in {} shards, expected 1: the shards were cut differently", r, covered[r]);
}

}  // namespace

ShardRange parseShardRange(const std::string& text, const std::string& option) {
    const size_t dash = text.find('-');
    uint32_t a = 0, b = 0;
    auto number = [](std::string_view s, uint32_t& v) {
        auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
        return ec == std::errc() && end == s.data() + s.size() && !s.empty();
    };
    if (dash == std::string::npos || !number(std::string_view(text).substr(0, dash), a) ||
        !number(std::string_view(text).substr(dash + 1), b) || a > b || b >= 65536)
        fail(option, "expected A-B with 0 <= A <= B < 65536 (shards A to B), got \"{}\"", text);
    return {a, b + 1};
}

std::string combinedFilePath(const std::string& dir, ShardRange range, uint32_t count) {
    return (fs::path(dir) / fmt::format("shards-{}-{}-of-{}.pnpart", range.first, range.end - 1, count)).string();
}

uint32_t mergeShardFiles(const std::string& dir, const BakeIdentity& id, const LightSamples& samples,
                         VisibilityMasks& masks) {
    Expected e{id.sceneHash, id.contentHash, masks.receivers(), uint32_t(masks.groups),
               [&id](const PartialHeader& h) { return id.settingsHash(ShardCut(h.cut), h.parts); }, "this one"};
    Coverage coverage;
    std::vector<uint8_t> covered(masks.receivers(), 0);
    PartialHeader first;
    std::string firstPath;
    for (const std::string& path : shardFilesOf(dir)) {
        PartialFile f = readPartialFile(path);
        if (firstPath.empty()) first = f.header, firstPath = path;
        checkShard(f, first, firstPath, e);
        coverage.add(f.header, path);
        if (ShardCut(f.header.cut) == ShardCut::Blockers) requireEveryReceiver(f);
        addPartialMasks(f, samples, masks, covered);
    }
    requireCovered(coverage, {0, first.parts}, first.parts, dir);
    if (ShardCut(first.cut) != ShardCut::Blockers) requireOncePerReceiver(covered, dir);
    return first.parts;
}

std::string combineShardFiles(const std::vector<std::string>& inputs, std::optional<ShardRange> range,
                              const std::string& outDir) {
    std::vector<std::string> files;
    for (const std::string& input : inputs) {
        std::error_code ec;
        if (fs::is_directory(input, ec)) {
            for (const std::string& f : shardFilesOf(input)) {
                // A combine of one range reads only the files of its range: the header says which.
                const PartialHeader h = range ? readPartialHeader(f) : PartialHeader{};
                if (!range || (h.part < range->end && h.partEnd > range->first)) files.push_back(f);
            }
        } else {
            files.push_back(input);
        }
    }
    if (files.empty()) fail(inputs.empty() ? std::string("combine") : inputs.front(), "no shard files in the range");
    Coverage coverage;
    PartialHeader first;
    std::string firstPath;
    std::vector<uint8_t> states, covered;
    VisibilityMasks masks;
    Expected expected;  ///< the first file's bake, which every other must be
    for (const std::string& path : files) {
        PartialFile f = readPartialFile(path);
        if (firstPath.empty()) {
            first = f.header, firstPath = path;
            states.assign(size_t(first.receivers), uint8_t(ReceiverState::Absent));
            covered.assign(size_t(first.receivers), 0);
            masks = VisibilityMasks(size_t(first.receivers), int(first.groups));
            expected = Expected{first.sceneHash, first.contentHash, first.receivers, first.groups,
                                [&first](const PartialHeader&) { return first.settingsHash; }, firstPath};
        }
        checkShard(f, first, firstPath, expected);
        if (range && (f.header.part < range->first || f.header.partEnd > range->end))
            fail(path, "covers shards {}-{}, across the edge of the range {}-{}", f.header.part, f.header.partEnd - 1,
                 range->first, range->end - 1);
        coverage.add(f.header, path);
        const bool byBlockers = ShardCut(f.header.cut) == ShardCut::Blockers;
        if (byBlockers) requireEveryReceiver(f);
        const uint64_t* words = f.words.data();
        for (size_t r = 0; r < f.state.size(); ++r) {
            if (f.state[r] == uint8_t(ReceiverState::Absent)) continue;
            if (!byBlockers && covered[r]++) fail(path, "receiver {} is in two shards: the shards were cut differently", r);
            states[r] = std::max(states[r], f.state[r]);  // absent < clear < partial < full umbra
            if (f.state[r] != uint8_t(ReceiverState::Partial)) continue;
            uint64_t* row = masks.row(r);
            for (uint32_t k = 0; k < first.groups; ++k) row[k] |= words[k];
            words += first.groups;
        }
    }
    if (range && range->end > first.parts)  // shards that cannot exist are not "missing"
        fail("--range", "{}-{} goes past the last shard of this bake ({} shards: 0-{})", range->first, range->end - 1,
             first.parts, first.parts - 1);
    const ShardRange covers = range ? *range : coverage.span();
    requireCovered(coverage, covers, first.parts, range ? fmt::format("shards {}-{}", covers.first, covers.end - 1) : firstPath);
    PartialHeader h = first;
    h.part = covers.first, h.partEnd = covers.end;
    std::error_code ec;
    fs::path existing = fs::absolute(outDir, ec);  // the nearest folder that is already there
    while (!existing.empty() && !fs::exists(existing, ec) && existing.has_parent_path() && existing != existing.parent_path())
        existing = existing.parent_path();
    fs::create_directories(outDir, ec);
    if (ec) fail(outDir, "cannot create the shard directory: {}", ec.message());
    const std::string out = combinedFilePath(outDir, covers, first.parts);
    try {
        writePartialStates(out, h, states, masks);
    } catch (...) {
        // A failed combine leaves none of the folders it made.
        for (fs::path made = fs::absolute(outDir, ec); made != existing && made.has_parent_path() && fs::is_empty(made, ec);
             made = made.parent_path())
            if (!fs::remove(made, ec)) break;
        throw;
    }
    return out;
}

}  // namespace penumbra
