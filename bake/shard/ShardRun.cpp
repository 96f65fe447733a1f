#include "bake/shard/ShardRun.h"

#include "bake/cast/PenumbraCaster.h"
#include "stream/util/Error.h"

#include <algorithm>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <map>

namespace penumbra {
namespace fs = std::filesystem;

void parseShardSpec(const std::string& text, const std::string& option, ShardSettings& out) {
    const size_t slash = text.find('/');
    uint32_t index = 0, count = 0;
    auto number = [&](std::string_view s, uint32_t& v) {
        auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
        return ec == std::errc() && end == s.data() + s.size() && !s.empty();
    };
    if (slash == std::string::npos || !number(std::string_view(text).substr(0, slash), index) ||
        !number(std::string_view(text).substr(slash + 1), count) || count == 0 || count > 65536 || index >= count)
        fail(option, "expected I/N with 0 <= I < N <= 65536 (shard I of N), got \"{}\"", text);
    out.index = index, out.count = count;
}

ShardCut parseShardCut(const std::string& text, const std::string& option) {
    if (text == "receivers") return ShardCut::Receivers;
    if (text == "blockers") return ShardCut::Blockers;
    if (text == "auto") return ShardCut::Automatic;
    fail(option, "expected receivers, blockers or auto, got \"{}\"", text);
}

const char* shardCutName(ShardCut cut) {
    return cut == ShardCut::Receivers ? "receivers" : cut == ShardCut::Blockers ? "blockers" : "auto";
}

ShardCut resolveShardCut(ShardCut cut, size_t receivers, uint32_t shards) {
    if (cut != ShardCut::Automatic) return cut;
    return receivers >= kMinReceiversPerShard * size_t(shards) ? ShardCut::Receivers : ShardCut::Blockers;
}

uint64_t BakeIdentity::settingsHash(ShardCut cut, uint32_t shards) const {
    Fnv64 h;
    h.addValue(methodHash), h.addValue(uint32_t(cut)), h.addValue(shards);
    return h.value;
}

BakeIdentity bakeIdentity(const std::string& sceneFile, const std::string& methodKey, const ReceiverSet& receivers,
                          const std::vector<uint32_t>& sampleSets, const LightSamples& samples) {
    BakeIdentity id;
    std::ifstream in(sceneFile, std::ios::binary);
    if (!in) fail(sceneFile, "cannot read the scene file to hash it");
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    Fnv64 scene;
    scene.add(bytes.data(), bytes.size());
    id.sceneHash = scene.value;
    Fnv64 method;
    method.add(methodKey.data(), methodKey.size());
    id.methodHash = method.value;
    Fnv64 content;
    content.addValue(uint64_t(receivers.size()));
    content.add(receivers.position.data(), receivers.position.size() * sizeof(glm::vec3));
    content.add(receivers.normal.data(), receivers.normal.size() * sizeof(glm::vec3));
    content.add(sampleSets.data(), sampleSets.size() * sizeof(uint32_t));
    content.add(samples.positions.data(), samples.positions.size() * sizeof(glm::vec3));
    for (const LightSampleGroup& g : samples.groups) content.addValue(g.first), content.addValue(g.count);
    id.contentHash = content.value;
    return id;
}

std::string shardFilePath(const std::string& dir, uint32_t index, uint32_t count) {
    return (fs::path(dir) / ("shard-" + std::to_string(index) + "-of-" + std::to_string(count) + ".pnpart")).string();
}

std::vector<uint32_t> shardReceivers(const ReceiverSet& receivers, const std::vector<uint32_t>& ids, uint32_t index,
                                     uint32_t count) {
    if (count <= 1) return ids;
    if (ids.size() < count) {  // fewer receivers than shards: the first ones get one each
        if (index < ids.size()) return {ids[index]};
        return {};
    }
    return partitionReceivers(receivers, ids, int(count))[index];
}

BlockerShardSource::BlockerShardSource(TriangleSource& inner, uint32_t index, uint32_t count)
    : inner_(inner), index_(index), count_(count) {}

size_t BlockerShardSource::read(std::span<Triangle> out) {
    size_t filled = 0;
    while (filled < out.size()) {
        // Enough of the inner stream to fill the rest of out, in one read.
        buffer_.resize(std::min<size_t>((out.size() - filled) * count_, size_t(1) << 16));
        const size_t n = inner_.read(buffer_);
        if (n == 0) break;
        for (size_t i = 0; i < n; ++i, ++position_)
            if (position_ % count_ == index_) {
                if (filled == out.size()) fail(inner_.name(), "internal: shard buffer overrun");
                out[filled++] = buffer_[i];
            }
    }
    return filled;
}

void BlockerShardSource::rewind() {
    inner_.rewind();
    position_ = 0;
}

std::optional<uint64_t> BlockerShardSource::sizeHint() const {
    const std::optional<uint64_t> all = inner_.sizeHint();
    if (!all) return std::nullopt;
    return *all / count_ + (*all % count_ > index_ ? 1 : 0);
}

void writeShardFile(const ShardSettings& settings, ShardCut cut, const BakeIdentity& id, const LightSamples& samples,
                    const VisibilityMasks& masks, std::span<const uint8_t> present) {
    PartialHeader h;
    h.role = PartialHeader::kShard;
    h.sceneHash = id.sceneHash, h.settingsHash = id.settingsHash(cut, settings.count), h.contentHash = id.contentHash;
    h.cut = uint32_t(cut), h.part = settings.index, h.parts = settings.count;
    h.receivers = present.size(), h.groups = uint32_t(masks.groups);
    h.lightFirstGroup = samples.lightFirstGroup;
    std::error_code ec;
    fs::create_directories(settings.dir, ec);
    if (ec) fail(settings.dir, "cannot create the shard directory: {}", ec.message());
    writePartialFile(shardFilePath(settings.dir, settings.index, settings.count), h, samples, masks, present);
}

namespace {

/// The shard files of @p dir, by name: every regular `*.pnpart` file.
std::vector<std::string> shardFilesOf(const std::string& dir) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) fail(dir, "not a directory of shard files");
    std::vector<std::string> files;
    for (const fs::directory_entry& e : fs::directory_iterator(dir, ec))
        if (e.path().extension() == ".pnpart" && e.path().filename().string().starts_with("shard-") &&
            e.is_regular_file(ec))
            files.push_back(e.path().string());
    if (ec) fail(dir, "cannot list the shard directory: {}", ec.message());
    if (files.empty()) fail(dir, "no shard files (shard-I-of-N.pnpart); bake them with --shard I/N --shard-dir {}", dir);
    std::sort(files.begin(), files.end());
    return files;
}

/// Refuses @p f unless it is a shard of the bake @p id, cut like @p first.
void checkShard(const PartialFile& f, const PartialFile& first, const BakeIdentity& id, size_t receivers, int groups) {
    const PartialHeader& h = f.header;
    if (h.role != PartialHeader::kShard) fail(f.path, "a checkpoint, not a shard file");
    if (h.sceneHash != id.sceneHash) fail(f.path, "shard of another scene file (scene hash {:016x}, this one {:016x})", h.sceneHash, id.sceneHash);
    if (h.parts != first.header.parts)
        fail(f.path, "shard {} of {}, but {} is of {}", h.part, h.parts, first.path, first.header.parts);
    if (h.cut != first.header.cut)
        fail(f.path, "cut by {}, but {} is cut by {}", shardCutName(ShardCut(h.cut)), first.path,
             shardCutName(ShardCut(first.header.cut)));
    if (h.settingsHash != id.settingsHash(ShardCut(h.cut), h.parts))
        fail(f.path, "shard baked with other settings (--method or its options)");
    if (h.contentHash != id.contentHash || h.receivers != receivers || h.groups != uint32_t(groups))
        fail(f.path, "shard of other receivers or light samples ({} receivers, {} groups; this bake has {} and {})",
             h.receivers, h.groups, receivers, groups);
}

}  // namespace

uint32_t mergeShardFiles(const std::string& dir, const BakeIdentity& id, const LightSamples& samples,
                         VisibilityMasks& masks) {
    const std::vector<std::string> files = shardFilesOf(dir);
    std::map<uint32_t, std::string> seen;  // shard index -> its file
    std::vector<uint8_t> covered(masks.receivers(), 0);
    PartialFile first;
    for (const std::string& path : files) {
        PartialFile f = readPartialFile(path);
        if (first.path.empty()) first = PartialFile{f.path, f.header, {}, {}};
        checkShard(f, first, id, masks.receivers(), masks.groups);
        auto [it, fresh] = seen.emplace(f.header.part, path);
        if (!fresh) fail(path, "duplicate of shard {} of {} (also in {})", f.header.part, f.header.parts, it->second);
        addPartialMasks(f, samples, masks, covered);
    }
    const uint32_t parts = first.header.parts;
    std::string missing;
    for (uint32_t i = 0, listed = 0; i < parts; ++i)
        if (!seen.count(i) && listed++ < 8) missing += (missing.empty() ? "" : ", ") + std::to_string(i);
    if (seen.size() != parts)
        fail(dir, "missing {} of {} shards ({}{}); rerun them with --shard I/{}", parts - seen.size(), parts, missing,
             parts - seen.size() > 8 ? ", ..." : "", parts);
    const bool byBlockers = ShardCut(first.header.cut) == ShardCut::Blockers;
    for (size_t r = 0; r < covered.size(); ++r)
        if (covered[r] != (byBlockers ? parts : 1u))
            fail(dir, "receiver {} is in {} shards, expected {}: the shards were cut differently", r, covered[r],
                 byBlockers ? parts : 1u);
    return parts;
}

}  // namespace penumbra
