#pragma once
/// @file IndexedSource.h
/// @brief Base for generators whose i-th triangle is a pure function of i. Chunks are produced on
/// demand and may be filled in parallel, yet the stream is identical for every thread count.

#include "stream/TriangleSource.h"

#include <cstdint>
#include <string>

namespace penumbra {

class IndexedSource : public TriangleSource {
public:
    IndexedSource(std::string name, uint64_t count) : name_(std::move(name)), count_(count) {}
    size_t read(std::span<Triangle> out) override;
    void rewind() override { next_ = 0; }
    std::string name() const override { return name_; }
    std::optional<uint64_t> sizeHint() const override { return count_; }

protected:
    /// Writes triangle @p index (< count) to @p out. Must be thread-safe and deterministic.
    virtual void triangle(uint64_t index, Triangle& out) const = 0;

private:
    std::string name_;
    uint64_t count_, next_ = 0;
};

}  // namespace penumbra
