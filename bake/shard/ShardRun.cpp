#include "bake/shard/ShardRun.h"

#include "bake/cast/PenumbraCaster.h"
#include "stream/util/Error.h"
#include "stream/util/InputFile.h"

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

ShardCut resolveShardCut(ShardCut cut, size_t receivers, uint32_t shards, bool tiles) {
    if (cut != ShardCut::Automatic) return cut;
    return tiles && receivers >= kMinReceiversPerShard * size_t(shards) ? ShardCut::Receivers : ShardCut::Blockers;
}

uint64_t BakeIdentity::settingsHash(ShardCut cut, uint32_t shards) const {
    Fnv64 h;
    h.addValue(methodHash), h.addValue(uint32_t(cut)), h.addValue(shards);
    // How the blockers are dealt out: shards of an older binary, which dealt them otherwise, must
    // not be merged with these (2: blocks of the source stream, BlockCyclicSource).
    if (cut == ShardCut::Blockers) h.addValue(uint32_t(2));
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
    // The files the scene names are part of it: a geometry file changed under the same scene
    // file makes another scene.
    scene.addValue(recordedInputsFingerprint());
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

std::optional<std::vector<uint32_t>> receiverShareOf(const ShardSettings& settings, const ReceiverSet& receivers, bool tiles) {
    if (!settings.casting() || settings.count <= 1 || !tiles) return std::nullopt;
    if (resolveShardCut(settings.cut, receivers.size(), settings.count, tiles) != ShardCut::Receivers) return std::nullopt;
    std::vector<uint32_t> ids(receivers.size());
    for (uint32_t r = 0; r < ids.size(); ++r) ids[r] = r;
    return shardReceivers(receivers, ids, settings.index, settings.count);
}

uint32_t receiverSharesBeforeScan(const ShardSettings& settings, bool tiles) {
    const bool cut = settings.casting() && settings.count > 1 && tiles && settings.cut == ShardCut::Receivers;
    return cut ? settings.count : 1;
}

std::optional<BlockShare> blockerShareOf(const ShardSettings& settings, size_t receivers, uint64_t triangles, bool tiles) {
    if (!settings.casting() || settings.count <= 1) return std::nullopt;
    if (resolveShardCut(settings.cut, receivers, settings.count, tiles) != ShardCut::Blockers) return std::nullopt;
    return BlockShare{settings.index, settings.count, blockSizeForShares(triangles, settings.count)};
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

}  // namespace penumbra
