#pragma once
/// @file PrefetchSource.h
/// @brief Reads a source ahead on a background thread, so that file reads, decompression or
/// generation overlap with whatever consumes the triangles (casting). Order is preserved exactly,
/// so the stream is the same as the wrapped source's. When no thread can be started (a process
/// or address-space limit), it reads in the caller's thread instead.

#include "stream/TriangleSource.h"

#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace penumbra {

class PrefetchSource final : public TriangleSource {
public:
    /// @param inner the source to read ahead; owned.
    /// @param chunkTriangles triangles per read-ahead chunk.
    /// @param depth chunks held ahead (memory: depth x chunkTriangles x 40 bytes).
    explicit PrefetchSource(TriangleSourcePtr inner, size_t chunkTriangles = kTriangleChunk, size_t depth = 4);
    ~PrefetchSource() override;

    /// @throw whatever the inner source threw, at the position in the stream where it threw.
    size_t read(std::span<Triangle> out) override;
    void rewind() override;
    /// @brief rewind(), then read ahead from @p wrap(the inner source) from now on: a wrapper that
    /// skips (a shard's share, stream/BlockCyclicSource.h) skips on the read-ahead thread, in the
    /// inner source itself, instead of reading what it drops.
    void rewindWrapped(const std::function<TriangleSourcePtr(TriangleSourcePtr)>& wrap);
    std::string name() const override { return inner_->name(); }
    std::optional<uint64_t> sizeHint() const override { return inner_->sizeHint(); }
    std::optional<uint64_t> knownSize() const override { return inner_->knownSize(); }
    std::vector<uint64_t> costRuns() const override { return inner_->costRuns(); }
    /// The inner source's bytes, the chunks held ahead and the one being handed out.
    uint64_t residentBytes() const override {
        return inner_->residentBytes() + (depth_ + 2) * chunkTriangles_ * sizeof(Triangle);
    }
    std::string residentDetail() const override { return inner_->residentDetail(); }
    /// The inner source's part of the triangles last read: a read stops where the part changes.
    uint32_t part() const override { return inline_ ? inner_->part() : currentPart_; }

private:
    /// One read of the inner source, and the part it came from.
    struct Chunk {
        std::vector<Triangle> triangles;
        uint32_t part = 0;
    };
    void start();
    void stop();
    void run();

    TriangleSourcePtr inner_;
    const size_t chunkTriangles_, depth_;
    std::mutex mutex_;
    std::condition_variable changed_;
    std::deque<Chunk> ready_;
    Chunk current_;
    size_t currentPos_ = 0;
    uint32_t currentPart_ = 0;  ///< the part of the last read's triangles
    bool finished_ = false, stopping_ = false;
    std::exception_ptr error_;
    std::thread thread_;
    bool inline_ = false;  ///< no thread could be started: read() reads the inner source itself
};

}  // namespace penumbra
