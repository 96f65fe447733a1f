#include "bake/output/BakeDump.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/util/JsonParams.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>

namespace penumbra {

namespace {

void writeDumpFiles(const std::filesystem::path& base, const ReceiverSet& receivers, std::span<const uint32_t> sampleSets,
                    const LightSamples& samples, const VisibilityMasks& masks, const ReceiverEpsilon& epsilon);

}  // namespace

void writeBakeDump(const std::string& dir, const ReceiverSet& receivers, std::span<const uint32_t> sampleSets,
                   const LightSamples& samples, const VisibilityMasks& masks, const ReceiverEpsilon& epsilon) {
    std::filesystem::path base(dir);
    std::error_code ec;
    const bool existed = std::filesystem::exists(base, ec);
    // Through ensureParentDirectory(), so that the folder belongs to the open OutputSet: a signal
    // before the outputs are in place removes it, as a failure below does.
    ensureParentDirectory((base / "rule.json").string());
    try {
        writeDumpFiles(base, receivers, sampleSets, samples, masks, epsilon);
    } catch (...) {
        // No output appears half-written: a directory made for a dump that failed (a full disk)
        // goes too (remove() takes it only if it is empty, as the files are linked at the end).
        if (!existed) std::filesystem::remove(base, ec);
        throw;
    }
}

namespace {

void writeDumpFiles(const std::filesystem::path& base, const ReceiverSet& receivers, std::span<const uint32_t> sampleSets,
                    const LightSamples& samples, const VisibilityMasks& masks, const ReceiverEpsilon& epsilon) {
    const uint64_t n = receivers.size(), k = uint64_t(samples.sampleCount);
    std::vector<float> rec(n * 7);
    for (size_t i = 0; i < n; ++i) {
        const glm::vec3 &x = receivers.position[i], &nn = receivers.normal[i];
        float row[7] = {x.x, x.y, x.z, nn.x, nn.y, nn.z, float(sampleSets[i])};
        std::copy(row, row + 7, rec.begin() + i * 7);
    }
    uint64_t recShape[2] = {n, 7};
    writeNpy((base / "receivers.npy").string(), "<f4", recShape, rec.data(), rec.size() * sizeof(float));

    std::vector<float> homogeneous(samples.positions.size() * 4);
    for (size_t i = 0; i < samples.positions.size(); ++i) {
        const glm::vec3& p = samples.positions[i];
        const float w = float(samples.sampleW(uint32_t(i % uint64_t(samples.sampleCount))));
        float row[4] = {p.x, p.y, p.z, w};
        std::copy(row, row + 4, homogeneous.begin() + i * 4);
    }
    uint64_t sampleShape[3] = {uint64_t(samples.sets), k, 4};
    writeNpy((base / "samples.npy").string(), "<f4", sampleShape, homogeneous.data(), homogeneous.size() * sizeof(float));

    std::vector<uint64_t> dense = masks.toDumpLayout(samples);
    uint64_t maskShape[2] = {n, (k + 63) / 64};
    writeNpy((base / "masks.npy").string(), "<u8", maskShape, dense.data(), dense.size() * sizeof(uint64_t));

    const nlohmann::json rule = {{"format", kDumpFormat}, {"epsilon", epsilon.relative}, {"epsilon_length", epsilon.length}};
    const std::string text = rule.dump(2) + "\n";
    writeFileAtomically((base / "rule.json").string(),
                        std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
}

ReceiverEpsilon readRule(const std::string& path) {
    const nlohmann::json rule = readJsonFile(path);
    JsonParams j(rule, path, "");
    const int64_t format = j.integer("format", 0, 0, 1 << 20);
    if (format != kDumpFormat)
        fail(j.where("format"), "dump format {} is not supported (this penumbra reads format {})", format, kDumpFormat);
    ReceiverEpsilon e;
    e.relative = j.number("epsilon");
    e.length = j.number("epsilon_length");
    if (!(e.relative >= 0 && std::isfinite(e.relative))) fail(j.where("epsilon"), "must be finite and non-negative");
    if (!(e.length > 0 && std::isfinite(e.length))) fail(j.where("epsilon_length"), "must be finite and positive");
    j.finish();
    return e;
}

}  // namespace

BakeDumpReader::BakeDumpReader(const std::string& dir)
    : dir_(dir), receiverRows_(path("receivers.npy")), maskRows_(path("masks.npy")) {
    const NpyHeader &rh = receiverRows_.header(), &mh = maskRows_.header();
    if (rh.dtype != "<f4" || rh.shape.size() != 2 || rh.shape[1] != 7) fail(path("receivers.npy"), "expected float32 N x 7");
    const NpyArray s = readNpy(path("samples.npy"));
    if (s.dtype != "<f4" || s.shape.size() != 3 || s.shape[2] != 4)
        fail(path("samples.npy"), "expected float32 S x K x 4 (x, y, z, w); a dump of format {} is needed", kDumpFormat);
    sets_ = s.shape[0], samplesPerSet_ = s.shape[1], receiverCount_ = rh.shape[0];
    if (sets_ == 0) fail(path("samples.npy"), "has no sample sets");
    samples_ = npyAsFloat32(s, path("samples.npy"));
    for (size_t i = 0; i < samples_.size(); i += 4)
        if (!std::isfinite(samples_[i]) || !std::isfinite(samples_[i + 1]) || !std::isfinite(samples_[i + 2]) ||
            (samples_[i + 3] != 0.0f && samples_[i + 3] != 1.0f))
            fail(path("samples.npy"), "sample {} of set {} is not finite or its w is neither 0 nor 1",
                 (i / 4) % samplesPerSet_, (i / 4) / samplesPerSet_);
    if (mh.dtype != "<u8" || mh.shape.size() != 2 || mh.shape[0] != receiverCount_ || mh.shape[1] != maskWords())
        fail(path("masks.npy"), "expected uint64 {} x {} to match receivers.npy and samples.npy", receiverCount_, maskWords());
    epsilon_ = readRule(path("rule.json"));
}

std::string BakeDumpReader::path(const char* name) const { return (std::filesystem::path(dir_) / name).string(); }

glm::dvec4 BakeDumpReader::sample(uint64_t set, uint64_t k) const {
    const float* s = samples_.data() + (set * samplesPerSet_ + k) * 4;
    return {s[0], s[1], s[2], s[3]};
}

void BakeDumpReader::next(uint64_t rows, std::vector<DumpReceiver>& receivers, std::vector<uint64_t>& masks) {
    receiverRows_.next(rows, rawReceivers_);
    maskRows_.next(rows, masks);
    receivers.resize(rows);
    for (uint64_t i = 0; i < rows; ++i) {
        const float* p = rawReceivers_.data() + i * 7;
        const float set = p[6];
        if (!(set >= 0.0f && set < float(sets_) && set == std::floor(set)))
            fail(path("receivers.npy"), "receiver {}: sample-set index {} is not an integer in [0, {})", rowsRead_ + i,
                 set, sets_);
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
            fail(path("receivers.npy"), "receiver {}: position is not finite", rowsRead_ + i);
        receivers[i] = {{p[0], p[1], p[2]}, {p[3], p[4], p[5]}, uint32_t(set)};
        // Bits past the last sample name samples that do not exist (a compare would report them,
        // and classify them from beyond samples.npy).
        const uint64_t words = maskWords(), used = samplesPerSet_ - 64 * (words - 1);
        if (const uint64_t last = masks[size_t(i * words + words - 1)]; used < 64 && (last >> used) != 0)
            fail(path("masks.npy"), "receiver {}: bits set above its {} samples (last word 0x{:016x})", rowsRead_ + i,
                 samplesPerSet_, last);
    }
    rowsRead_ += rows;
}

}  // namespace penumbra
