#pragma once
/// @file IndexedSource.h
/// @brief Base for generators whose i-th triangle is a pure function of i. Chunks are produced on
/// demand and may be filled in parallel, yet the stream is identical for every thread count.

#include "stream/TriangleSource.h"

#include <algorithm>
#include <cstdint>
#include <span>
#include <string>

namespace penumbra {

class IndexedSource : public TriangleSource {
public:
    IndexedSource(std::string name, uint64_t count) : name_(std::move(name)), count_(count) {}
    /// @brief Fills @p out with the next triangles; the chunk is split into ranges that are filled
    /// in parallel (fill()), so the result never depends on the number of threads.
    size_t read(std::span<Triangle> out) override;
    void rewind() override { next_ = 0; }
    /// Jumps: nothing is generated for the skipped indices.
    uint64_t skip(uint64_t count) override {
        const uint64_t n = std::min(count, count_ - next_);
        next_ += n;
        return n;
    }
    std::string name() const override { return name_; }
    std::optional<uint64_t> sizeHint() const override { return count_; }

protected:
    /// Writes triangle @p index (< count) to @p out. Must be thread-safe and deterministic.
    virtual void triangle(uint64_t index, Triangle& out) const = 0;

    /// @brief Writes triangles first .. first + out.size() - 1 to @p out.
    ///
    /// The default calls triangle() for each index. Generators whose triangles come in groups
    /// (a grass blade, a flower) override it to build each group once instead of once per
    /// triangle; the output must equal what triangle() would give. Thread-safe, deterministic.
    virtual void fill(uint64_t first, std::span<Triangle> out) const;

private:
    std::string name_;
    uint64_t count_, next_ = 0;
};

/// @brief An IndexedSource made of items (a blade, a flower, a box) that each emit the same
/// number of triangles. Subclasses build one whole item at a time; items cut by a chunk
/// boundary are built into a scratch buffer and only the requested part is copied.
class ItemSource : public IndexedSource {
public:
    /// @param items number of items; @param perItem triangles per item, 1..kMaxPerItem
    ItemSource(std::string name, uint64_t items, uint32_t perItem);

    /// Upper bound on perItem, so that the scratch buffer lives on the stack.
    static constexpr uint32_t kMaxPerItem = 256;

protected:
    /// Writes the perItem triangles of item @p item to @p out. Thread-safe, deterministic.
    virtual void item(uint64_t item, Triangle* out) const = 0;

    void triangle(uint64_t index, Triangle& out) const final;
    void fill(uint64_t first, std::span<Triangle> out) const final;

    uint32_t perItem() const { return perItem_; }

private:
    uint32_t perItem_;
};

}  // namespace penumbra
