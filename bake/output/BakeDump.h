#pragma once
/// @file BakeDump.h
/// @brief `--dump DIR`: the exact inputs and outputs of every relation of a bake, and its reader.
///
/// The format (version 2; docs/scene-format.md, "Dumps"), four files:
///  - `receivers.npy`: float32 N x 7, per receiver its position, normal and sample-set index;
///  - `samples.npy`: float32 S x K x 4, sample k of set s as homogeneous (x, y, z, w): w = 1 for a
///    point sample, w = 0 for a sun's direction towards the light (not normalised: it is the exact
///    float vector every method casts along). All lights' samples are concatenated in scene order;
///  - `masks.npy`: uint64 N x ceil(K / 64), bit k % 64 of word k / 64 set when sample k is blocked;
///  - `rule.json`: the blocking rule's parameters, {"format": 2, "epsilon": e, "epsilon_length": L},
///    so that eps(r) = e * max(|r|_inf, L) can be evaluated without the scene.
/// Receivers and masks are read a block of rows at a time, so dumps of millions of receivers are
/// compared in a few MB.

#include "bake/rule/BlockingRule.h"
#include "bake/light/Light.h"
#include "bake/cast/VisibilityMasks.h"
#include "receivers/ReceiverSet.h"
#include "stream/Npy.h"

#include <glm/vec4.hpp>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

inline constexpr int kDumpFormat = 2;

/// @brief Writes the four files of a dump into @p dir (created if missing).
/// @throw InputError naming the file when a write fails.
void writeBakeDump(const std::string& dir, const ReceiverSet& receivers, std::span<const uint32_t> sampleSets,
                   const LightSamples& samples, const VisibilityMasks& masks, const ReceiverEpsilon& epsilon);

/// @brief One receiver row of a dump.
struct DumpReceiver {
    glm::dvec3 position, normal;
    uint32_t sampleSet = 0;
};

/// @brief A dump opened for reading, with every value that indexes something validated.
class BakeDumpReader {
public:
    /// @throw InputError naming the file for a missing or malformed file, shapes that disagree,
    /// no sample sets, or a rule.json of another format.
    explicit BakeDumpReader(const std::string& dir);

    uint64_t receivers() const { return receiverCount_; }
    uint64_t sets() const { return sets_; }
    uint64_t samples() const { return samplesPerSet_; }
    uint64_t maskWords() const { return (samplesPerSet_ + 63) / 64; }
    const ReceiverEpsilon& epsilon() const { return epsilon_; }
    /// Sample @p k of set @p set as (x, y, z, w).
    glm::dvec4 sample(uint64_t set, uint64_t k) const;
    const std::vector<float>& rawSamples() const { return samples_; }

    /// @brief Reads the next @p rows receivers and their mask rows.
    /// @throw InputError naming receivers.npy for a sample-set index that is not an integer in
    /// [0, sets()) or a non-finite position.
    void next(uint64_t rows, std::vector<DumpReceiver>& receivers, std::vector<uint64_t>& masks);
    /// The raw float rows last read (for comparing two dumps' receivers bit for bit).
    const std::vector<float>& rawReceivers() const { return rawReceivers_; }

    std::string path(const char* name) const;

private:
    std::string dir_;
    NpyRowReader receiverRows_, maskRows_;
    std::vector<float> samples_;  ///< S x K x 4
    uint64_t receiverCount_ = 0, sets_ = 0, samplesPerSet_ = 0, rowsRead_ = 0;
    ReceiverEpsilon epsilon_;
    std::vector<float> rawReceivers_;
};

}  // namespace penumbra
