#pragma once
/// @file BlockCyclicSource.h
/// @brief One of N interleaved shares of another source: blocks of B consecutive triangles, dealt
/// out to the shares in turn (block k goes to share k mod N). A by-blockers shard casts its share
/// (bake/shard); the shares of 0..N-1 together hold every triangle exactly once.
///
/// The blocks of the other shares are skipped with TriangleSource::skip(), so a generator or a
/// file of fixed-size records makes or reads only its share; other sources read and drop them.

#include "stream/TriangleSource.h"

namespace penumbra {

/// @brief Which blocks of a stream one share holds.
struct BlockShare {
    uint32_t index = 0;    ///< the share, 0 <= index < count
    uint32_t count = 1;    ///< shares in all
    uint64_t block = 1;    ///< triangles per block, at least 1

    /// @brief The triangles of a stream of @p total that this share holds.
    uint64_t triangles(uint64_t total) const;
};

/// @brief A block size for dealing @p total triangles out to @p shares shares: about 64 blocks
/// per share, so that every share gets a spread of the stream (parts of a scene come one after
/// another), within [64, 65536] so that a skip is cheap against the work of a block.
uint64_t blockSizeForShares(uint64_t total, uint32_t shares);

class BlockCyclicSource final : public TriangleSource {
public:
    /// @param inner the whole stream; owned. @param share which blocks to hand out.
    BlockCyclicSource(TriangleSourcePtr inner, BlockShare share);

    size_t read(std::span<Triangle> out) override;
    void rewind() override;
    std::string name() const override { return inner_->name(); }
    std::optional<uint64_t> sizeHint() const override;
    std::optional<uint64_t> knownSize() const override;
    uint64_t residentBytes() const override { return inner_->residentBytes(); }
    std::string residentDetail() const override { return inner_->residentDetail(); }
    uint32_t part() const override { return inner_->part(); }

private:
    TriangleSourcePtr inner_;
    BlockShare share_;
    uint64_t leftInBlock_ = 0;  ///< triangles of the current block of this share still to hand out
    bool started_ = false;      ///< whether the first block of this share has been reached
    bool ended_ = false;        ///< the inner stream ended
};

}  // namespace penumbra
