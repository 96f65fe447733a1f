#include "bake/shard/Checkpoint.h"

#include "stream/util/Error.h"

#include <algorithm>
#include <cctype>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

namespace penumbra {
namespace fs = std::filesystem;

namespace {

/// "STEM-HASH." for the scene file @p sceneFile: its stem (letters, digits, '-', '_' and '.'
/// kept) and 8 hex digits of a hash of its absolute path. Two scene files' bakes that share a
/// checkpoint folder then keep their own files: with one name per tile, the second replaced the
/// first's checkpoints (noting them as another scene's), and removed them when it was done.
std::string scenePrefix(const std::string& sceneFile) {
    if (sceneFile.empty()) return "";
    std::string stem;
    for (char c : fs::path(sceneFile).stem().string())
        if (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.') stem += c;
    std::error_code ec;
    fs::path full = fs::weakly_canonical(fs::absolute(sceneFile), ec);
    if (ec) full = fs::absolute(sceneFile);
    Fnv64 hash;
    const std::string text = full.string();
    hash.add(text.data(), text.size());
    return fmt::format("{}-{:08x}.", stem.empty() ? "scene" : stem, uint32_t(hash.value ^ (hash.value >> 32)));
}

/// "shard-I-of-N." for a shard's checkpoints, else "". A shard's checkpoints are named by it too,
/// so that shards given one folder keep their own: with the same names they replaced each
/// other's, and a --resume then refused the other's.
std::string shardNamePart(const ShardSettings& settings) {
    return settings.casting() ? "shard-" + std::to_string(settings.index) + "-of-" + std::to_string(settings.count) + "." : "";
}

/// Whether @p head is a scene prefix as scenePrefix() makes it: "STEM-" then 8 hex digits and '.'.
bool isScenePrefix(const std::string& head) {
    if (head.size() < 11 || head.back() != '.' || head[head.size() - 10] != '-') return false;
    return std::all_of(head.end() - 9, head.end() - 1, [](char c) { return std::isxdigit(static_cast<unsigned char>(c)) != 0; });
}

}  // namespace

std::string checkpointNamePrefix(const std::string& sceneFile, const ShardSettings& settings) {
    return scenePrefix(sceneFile) + shardNamePart(settings);
}

Checkpoints::Checkpoints(const ShardSettings& settings, PartialHeader header, const LightSamples& samples, bool quiet,
                         const std::string& sceneFile)
    : settings_(settings), header_(std::move(header)), samples_(samples), quiet_(quiet),
      namePrefix_(checkpointNamePrefix(sceneFile, settings)) {
    header_.role = PartialHeader::kCheckpoint;
    std::error_code ec;
    // --resume promises saved work; a folder that is not there is more often a typo than a start.
    if (settings_.resume && !fs::exists(settings_.checkpointDir, ec))
        printWarning("--resume: {} does not exist, so there is nothing to resume; baking from the start", settings_.checkpointDir);
    madeFolder_ = fs::create_directories(settings_.checkpointDir, ec);
    if (ec || !fs::is_directory(settings_.checkpointDir, ec))
        fail(settings_.checkpointDir, "cannot create the checkpoint directory: {}", ec ? ec.message() : "not a directory");
    if (const char* kill = std::getenv("PENUMBRA_TEST_KILL_AFTER_TILES"); kill && *kill) killAfter_ = std::atol(kill);
}

Checkpoints::~Checkpoints() {
    std::error_code ec;
    if (madeFolder_ && fs::is_directory(settings_.checkpointDir, ec) && fs::is_empty(settings_.checkpointDir, ec) && !ec)
        fs::remove(settings_.checkpointDir, ec);
}

void Checkpoints::ensureFolder() const {
    // Another bake of this folder may have finished and removed it (a job requeued while the
    // first still ran lost its whole cast to "cannot create file").
    std::error_code ec;
    if (!fs::is_directory(settings_.checkpointDir, ec)) fs::create_directories(settings_.checkpointDir, ec);
}

std::string Checkpoints::pathOf(size_t tile, size_t tiles, const char* suffix) const {
    const std::string name = namePrefix_ + "tile-" + std::to_string(tile) + "-of-" + std::to_string(tiles) + suffix + ".pnpart";
    return (fs::path(settings_.checkpointDir) / name).string();
}

void Checkpoints::reject(const std::string& path, const std::string& why) {
    if (settings_.resume) fail(path, "{}; remove it or bake without --resume", why);
    if (!quiet_) printNote("{}: ignoring the checkpoint: {}", path, why);
}

std::string Checkpoints::misnamedWhy(const PartialHeader& h, size_t tile, size_t tiles) {
    if (h.part == tile && h.parts == tiles) return {};
    return fmt::format("holds tile {} of {}, not tile {} of {} as its name says (renamed?)", h.part, h.parts, tile, tiles);
}

std::optional<PartialFile> Checkpoints::readMatching(const std::string& path, uint32_t role, size_t tile, size_t tiles,
                                                     std::span<const uint32_t> ids) {
    std::error_code ec;
    if (!fs::exists(path, ec)) return std::nullopt;
    PartialFile f;
    try {
        f = readPartialFile(path);
    } catch (const InputError& e) {
        if (settings_.resume) throw;
        if (!quiet_) printNote("ignoring the checkpoint: {}", e.what());
        return std::nullopt;
    }
    const PartialHeader& h = f.header;
    if (h.role != role) return reject(path, "not a checkpoint of this kind (a shard file or another role)"), std::nullopt;
    if (h.sceneHash != header_.sceneHash) return reject(path, "a checkpoint of another scene file"), std::nullopt;
    if (h.settingsHash != header_.settingsHash || h.cut != header_.cut)
        return reject(path, "a checkpoint of other settings (method, shard or cut)"), std::nullopt;
    if (h.contentHash != header_.contentHash || h.receivers != header_.receivers || h.groups != header_.groups)
        return reject(path, "a checkpoint of other receivers or light samples"), std::nullopt;
    if (const std::string why = misnamedWhy(h, tile, tiles); !why.empty()) return reject(path, why), std::nullopt;
    // The tile must hold exactly these receivers: another memory budget tiles differently.
    size_t present = 0;
    for (uint8_t s : f.state) present += s != uint8_t(ReceiverState::Absent);
    bool same = present == ids.size();
    for (size_t i = 0; same && i < ids.size(); ++i) same = f.state[ids[i]] != uint8_t(ReceiverState::Absent);
    if (!same) return reject(path, "a checkpoint of another tiling (--memory-budget or --threads changed)"), std::nullopt;
    return f;
}

bool Checkpoints::sameBake(const std::string& path) const {
    try {  // only this bake's files: a folder may hold another bake's, which are not ours to judge
        return isThisBake(readPartialHeader(path));
    } catch (const InputError&) {
        return false;  // damaged: its own bake reports it
    }
}

void Checkpoints::checkOtherTilings(size_t tiles) {
    if (tilingChecked_) return;
    tilingChecked_ = true;
    // "tile-T-of-M[.progress].pnpart" with another M: this bake under another memory budget or
    // thread count looks only for its own names, and would bake from the start without a word.
    // The same names under another scene prefix: this bake's scene file was moved (or copied)
    // since they were saved; they are this bake's if their header says so, and are adopted.
    std::vector<std::string> other;
    std::vector<std::pair<std::string, std::string>> moved;  // from, to
    std::error_code ec;
    const std::string& prefix = namePrefix_;
    const std::string shardPart = shardNamePart(settings_);
    for (const auto& entry : fs::directory_iterator(settings_.checkpointDir, ec)) {
        const std::string full = entry.path().filename().string();
        const bool ours = full.starts_with(prefix);
        std::string name = ours ? full.substr(prefix.size()) : "";  // from "tile-"
        if (!ours) {
            const size_t at = full.rfind(shardPart + "tile-");
            if (prefix.empty() || at == std::string::npos || !isScenePrefix(full.substr(0, at))) continue;  // another shard's
            name = full.substr(at + shardPart.size());
        }
        unsigned long t = 0, m = 0;
        int used = 0;
        if (std::sscanf(name.c_str(), "tile-%lu-of-%lu%n", &t, &m, &used) != 2) continue;
        const std::string rest = name.substr(size_t(used));
        if (rest != ".pnpart" && rest != ".progress.pnpart") continue;
        if (ours && m == tiles) {
            // Checked now, before any tile is cast: a misnamed file would otherwise stop a resumed
            // bake only when its tile comes up.
            if (settings_.resume) checkName(entry.path().string(), t, m);
            continue;
        }
        if (!sameBake(entry.path().string())) continue;
        if (ours) other.push_back(entry.path().string());
        else if (m == tiles && !fs::exists(fs::path(settings_.checkpointDir) / (prefix + name), ec))
            moved.emplace_back(entry.path().string(), (fs::path(settings_.checkpointDir) / (prefix + name)).string());
    }
    adoptMoved(moved);
    if (other.empty()) return;
    std::sort(other.begin(), other.end());
    const std::string why = fmt::format("a checkpoint of this bake in another tiling (this bake has {} tile(s); --memory-budget or --threads changed)", tiles);
    if (settings_.resume) fail(other.front(), "{}; remove it or bake without --resume", why);
    if (!quiet_) printNote("{}: ignoring {} checkpoint file(s) of this bake in another tiling (this bake has {} tile(s); --memory-budget or --threads changed)",
                           settings_.checkpointDir, other.size(), tiles);
    // Superseded by this bake's own: removed with them once the outputs are in place.
    written_.insert(written_.end(), other.begin(), other.end());
}

void Checkpoints::checkName(const std::string& path, size_t tile, size_t tiles) {
    PartialHeader h;
    try {
        h = readPartialHeader(path);
    } catch (const InputError&) {
        return;  // damaged: reported when its tile reads it
    }
    if (!isThisBake(h)) return;  // another bake's: reported, with the reason, when its tile reads it
    if (const std::string why = misnamedWhy(h, tile, tiles); !why.empty()) reject(path, why);
}

void Checkpoints::adoptMoved(std::vector<std::pair<std::string, std::string>> moved) {
    if (moved.empty()) return;
    std::sort(moved.begin(), moved.end());
    size_t adopted = 0;
    std::error_code ec;
    for (const auto& [from, to] : moved) {
        fs::rename(from, to, ec);  // within one folder: atomic; a failure leaves the tile to be cast
        adopted += !ec;
    }
    if (adopted && !quiet_)
        printNote("{}: using {} checkpoint file(s) of this bake saved under another path of its scene file (moved or copied)",
                  settings_.checkpointDir, adopted);
}

bool Checkpoints::restore(size_t tile, size_t tiles, std::span<const uint32_t> ids, VisibilityMasks& masks) {
    checkOtherTilings(tiles);
    const std::string path = pathOf(tile, tiles);
    const std::optional<PartialFile> f = readMatching(path, PartialHeader::kCheckpoint, tile, tiles, ids);
    if (!f) return false;
    std::vector<uint8_t> covered(masks.receivers(), 0);
    addPartialMasks(*f, samples_, masks, covered);
    written_.push_back(path);
    written_.push_back(pathOf(tile, tiles, ".progress"));  // left if a kill came between the two
    ++restored_;
    return true;
}

std::optional<TileProgress> Checkpoints::resumeTile(size_t tile, size_t tiles, std::span<const uint32_t> ids) {
    checkOtherTilings(tiles);
    progressClock_.reset(), chunksSinceSave_ = 0;
    const std::string path = pathOf(tile, tiles, ".progress");
    const std::optional<PartialFile> f = readMatching(path, PartialHeader::kTileProgress, tile, tiles, ids);
    if (!f) return std::nullopt;
    TileProgress p{f->header.replayed, f->header.replayHash, VisibilityMasks(ids.size(), int(header_.groups))};
    const uint64_t* words = f->words.data();
    for (size_t r = 0, i = 0; r < f->state.size(); ++r) {  // the present receivers are ids, in order
        const auto state = ReceiverState(f->state[r]);
        if (state == ReceiverState::Absent) continue;
        uint64_t* row = p.masks.row(i++);
        for (int k = 0; k < p.masks.groups; ++k)
            row[k] = state == ReceiverState::Full ? samples_.groups[k].fullMask() : state == ReceiverState::Partial ? words[k] : 0;
        if (state == ReceiverState::Partial) words += p.masks.groups;
    }
    written_.push_back(path);
    ++resumed_, skipped_ += p.replayed, lastSkipped_ = p.replayed;
    return p;
}

void Checkpoints::rejectProgress(size_t tile, size_t tiles) {
    reject(pathOf(tile, tiles, ".progress"), "the blockers replayed differ from the ones it holds (a geometry file changed?)");
    --resumed_, skipped_ -= lastSkipped_;
}

void Checkpoints::saveProgress(size_t tile, size_t tiles, std::span<const uint32_t> ids, const VisibilityMasks& masks,
                               uint64_t replayed, uint64_t replayHash) {
    PartialHeader h = header_;
    h.role = PartialHeader::kTileProgress;
    h.part = uint32_t(tile), h.parts = uint32_t(tiles), h.replayed = replayed, h.replayHash = replayHash;
    std::vector<uint8_t> present(size_t(header_.receivers), 0);
    for (uint32_t r : ids) present[r] = 1;
    const std::string path = pathOf(tile, tiles, ".progress");
    ensureFolder();
    writePartialFile(path, h, samples_, masks, present);
    written_.push_back(path);
    ++progressSaves_;
    progressPending_ = true;
    progressClock_.reset(), chunksSinceSave_ = 0;
}

void Checkpoints::save(size_t tile, size_t tiles, std::span<const uint32_t> ids, const VisibilityMasks& masks) {
    PartialHeader h = header_;
    h.part = uint32_t(tile), h.parts = uint32_t(tiles);
    std::vector<uint8_t> present(size_t(header_.receivers), 0);
    for (uint32_t r : ids) present[r] = 1;
    const std::string path = pathOf(tile, tiles);
    ensureFolder();
    writePartialFile(path, h, samples_, masks, present);
    written_.push_back(path);
    std::error_code ec;
    fs::remove(pathOf(tile, tiles, ".progress"), ec);  // the whole tile supersedes its progress
    ++saved_;
    progressPending_ = false;
    progressClock_.reset(), chunksSinceSave_ = 0;
    if (killAfter_ >= 0 && long(saved_) >= killAfter_) std::raise(SIGKILL);  // a real kill -9, for the tests
}

void Checkpoints::removeAll() noexcept {
    std::error_code ec;
    for (const std::string& path : written_) fs::remove(path, ec);
    written_.clear();
    // The folder too, when nothing else is in it: a completed bake leaves nothing of its
    // checkpoints behind (remove() leaves a folder that holds anything, and the current one).
    if (fs::is_directory(settings_.checkpointDir, ec) && fs::is_empty(settings_.checkpointDir, ec) && !ec &&
        !fs::equivalent(settings_.checkpointDir, fs::current_path(ec), ec))
        fs::remove(settings_.checkpointDir, ec);
}

}  // namespace penumbra
