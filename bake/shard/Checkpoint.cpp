#include "bake/shard/Checkpoint.h"

#include "stream/util/Error.h"

#include <csignal>
#include <cstdlib>
#include <filesystem>

namespace penumbra {
namespace fs = std::filesystem;

Checkpoints::Checkpoints(const ShardSettings& settings, PartialHeader header, const LightSamples& samples, bool quiet)
    : settings_(settings), header_(std::move(header)), samples_(samples), quiet_(quiet) {
    header_.role = PartialHeader::kCheckpoint;
    std::error_code ec;
    fs::create_directories(settings_.checkpointDir, ec);
    if (ec || !fs::is_directory(settings_.checkpointDir, ec))
        fail(settings_.checkpointDir, "cannot create the checkpoint directory: {}", ec ? ec.message() : "not a directory");
    if (const char* kill = std::getenv("PENUMBRA_TEST_KILL_AFTER_TILES"); kill && *kill) killAfter_ = std::atol(kill);
}

std::string Checkpoints::pathOf(size_t tile, size_t tiles) const {
    return (fs::path(settings_.checkpointDir) / ("tile-" + std::to_string(tile) + "-of-" + std::to_string(tiles) + ".pnpart"))
        .string();
}

void Checkpoints::reject(const std::string& path, const std::string& why) {
    if (settings_.resume) fail(path, "{}; remove it or bake without --resume", why);
    if (!quiet_) printNote("{}: ignoring the checkpoint: {}", path, why);
}

bool Checkpoints::restore(size_t tile, size_t tiles, std::span<const uint32_t> ids, VisibilityMasks& masks) {
    const std::string path = pathOf(tile, tiles);
    std::error_code ec;
    if (!fs::exists(path, ec)) return false;
    PartialFile f;
    try {
        f = readPartialFile(path);
    } catch (const InputError& e) {
        if (settings_.resume) throw;
        if (!quiet_) printNote("ignoring the checkpoint: {}", e.what());
        return false;
    }
    const PartialHeader& h = f.header;
    if (h.role != PartialHeader::kCheckpoint) return reject(path, "not a checkpoint"), false;
    if (h.sceneHash != header_.sceneHash) return reject(path, "a checkpoint of another scene file"), false;
    if (h.settingsHash != header_.settingsHash || h.cut != header_.cut)
        return reject(path, "a checkpoint of other settings (method, shard or cut)"), false;
    if (h.contentHash != header_.contentHash || h.receivers != header_.receivers || h.groups != header_.groups)
        return reject(path, "a checkpoint of other receivers or light samples"), false;
    // The tile must hold exactly these receivers: another memory budget tiles differently.
    size_t present = 0;
    for (uint8_t s : f.state) present += s != uint8_t(ReceiverState::Absent);
    bool same = present == ids.size();
    for (size_t i = 0; same && i < ids.size(); ++i) same = f.state[ids[i]] != uint8_t(ReceiverState::Absent);
    if (!same) return reject(path, "a checkpoint of another tiling (--memory-budget or --threads changed)"), false;
    std::vector<uint8_t> covered(masks.receivers(), 0);
    addPartialMasks(f, samples_, masks, covered);
    written_.push_back(path);
    ++restored_;
    return true;
}

void Checkpoints::save(size_t tile, size_t tiles, std::span<const uint32_t> ids, const VisibilityMasks& masks) {
    PartialHeader h = header_;
    h.part = uint32_t(tile), h.parts = uint32_t(tiles);
    std::vector<uint8_t> present(size_t(header_.receivers), 0);
    for (uint32_t r : ids) present[r] = 1;
    const std::string path = pathOf(tile, tiles);
    writePartialFile(path, h, samples_, masks, present);
    written_.push_back(path);
    ++saved_;
    if (killAfter_ >= 0 && long(saved_) >= killAfter_) std::raise(SIGKILL);  // a real kill -9, for the tests
}

void Checkpoints::removeAll() noexcept {
    std::error_code ec;
    for (const std::string& path : written_) fs::remove(path, ec);
    written_.clear();
}

}  // namespace penumbra
