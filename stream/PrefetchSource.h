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
    std::string name() const override { return inner_->name(); }
    std::optional<uint64_t> sizeHint() const override { return inner_->sizeHint(); }
    std::optional<uint64_t> knownSize() const override { return inner_->knownSize(); }
    /// The inner source's bytes, the chunks held ahead and the one being handed out.
    uint64_t residentBytes() const override {
        return inner_->residentBytes() + (depth_ + 2) * chunkTriangles_ * sizeof(Triangle);
    }
    std::string residentDetail() const override { return inner_->residentDetail(); }

private:
    void start();
    void stop();
    void run();

    TriangleSourcePtr inner_;
    const size_t chunkTriangles_, depth_;
    std::mutex mutex_;
    std::condition_variable changed_;
    std::deque<std::vector<Triangle>> ready_;
    std::vector<Triangle> current_;
    size_t currentPos_ = 0;
    bool finished_ = false, stopping_ = false;
    std::exception_ptr error_;
    std::thread thread_;
    bool inline_ = false;  ///< no thread could be started: read() reads the inner source itself
};

}  // namespace penumbra
