#pragma once
/// @file TriangleSource.h
/// @brief The streaming interface every geometry input implements (file readers, generators).
///
/// A source hands out triangles in caller-sized chunks and never promises to hold more than
/// one chunk plus whatever index data its format needs. Sources are the extension point of the
/// stream stage: readers, procedural generators and transforms all implement this interface.

#include "stream/Triangle.h"

#include <cstddef>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace penumbra {

class TriangleSource {
public:
    virtual ~TriangleSource() = default;

    /// @brief Fill the front of @p out with the next triangles.
    /// @return how many were written; 0 only at the end of the stream.
    /// @throw InputError naming the file and the problem when the input is malformed.
    virtual size_t read(std::span<Triangle> out) = 0;

    /// @brief Start again from the first triangle (sources are replayed by multi-pass bakes).
    virtual void rewind() = 0;

    /// @brief Pass over the next @p count triangles without handing them out, as if they had been
    /// read: the next read() starts after them. A by-blockers shard skips the blocks of other
    /// shards this way (bake/shard), so a source that can jump (a generator whose i-th triangle
    /// is a function of i, a file of fixed-size records) makes nothing it does not hand out.
    /// The default reads the triangles and drops them, which is right for every source.
    /// @return how many were skipped: fewer than @p count only at the end of the stream.
    /// @throw InputError as read() would, for the triangles the default reads.
    virtual uint64_t skip(uint64_t count);

    /// A name for messages: the file path or the generator type.
    virtual std::string name() const = 0;

    /// The triangle count when known up front (a .ptri header, a glTF accessor sum).
    virtual std::optional<uint64_t> sizeHint() const { return std::nullopt; }
    /// @brief sizeHint() when it is known without reading the input (an OBJ counts its faces in a
    /// first pass), for plans made before any work; nullopt otherwise.
    virtual std::optional<uint64_t> knownSize() const { return sizeHint(); }

    /// @brief Heap bytes the source holds at most while open (document tables, block caches,
    /// decoder buffers, read-ahead chunks), whatever the triangle count: its part of the memory
    /// plan. Known right after the source is opened, before any triangle is read.
    virtual uint64_t residentBytes() const { return 0; }
    /// @brief What dominates residentBytes() when one item does (a compressed primitive that
    /// must be decoded whole), for messages; empty otherwise.
    virtual std::string residentDetail() const { return {}; }
    /// Below this, a held item is not what a memory refusal is about: residentDetail() stays empty.
    static constexpr uint64_t kNotableResidentBytes = 16ull << 20;
    /// @brief Which part the triangles of the last read() came from, for a source that plays
    /// parts back to back (ConcatSource: a scene's geometry entries, in order): one read never
    /// mixes parts. 0 for a source of one part.
    virtual uint32_t part() const { return 0; }
    /// @brief Runs of consecutive triangles, in play order, whose cost to cast may differ run to
    /// run (a bucket replay's opaque triangles, then its cut-outs), for the progress estimate; they
    /// add up to sizeHint(). Empty when the source knows of none.
    virtual std::vector<uint64_t> costRuns() const { return {}; }
};

using TriangleSourcePtr = std::unique_ptr<TriangleSource>;

/// @brief Base of the sources that change what another source delivers triangle by triangle
/// (flags, transforms, alpha ids): everything but read() and rewind() is the inner source's.
class DecoratedSource : public TriangleSource {
public:
    explicit DecoratedSource(TriangleSourcePtr inner) : inner_(std::move(inner)) {}
    void rewind() override { inner_->rewind(); }
    std::string name() const override { return inner_->name(); }
    std::optional<uint64_t> sizeHint() const override { return inner_->sizeHint(); }
    std::optional<uint64_t> knownSize() const override { return inner_->knownSize(); }
    uint64_t residentBytes() const override { return inner_->residentBytes(); }
    std::string residentDetail() const override { return inner_->residentDetail(); }
    std::vector<uint64_t> costRuns() const override { return inner_->costRuns(); }

protected:
    TriangleSourcePtr inner_;
};

/// @brief A source over triangles already in memory (tests, small scenes).
class VectorSource final : public TriangleSource {
public:
    explicit VectorSource(std::vector<Triangle> triangles, std::string name = "memory")
        : triangles_(std::move(triangles)), name_(std::move(name)) {}
    size_t read(std::span<Triangle> out) override;
    void rewind() override { next_ = 0; }
    uint64_t skip(uint64_t count) override;
    std::string name() const override { return name_; }
    std::optional<uint64_t> sizeHint() const override { return triangles_.size(); }

private:
    std::vector<Triangle> triangles_;
    std::string name_;
    size_t next_ = 0;
};

/// @brief Plays several sources back to back, in order (a scene's geometry list).
class ConcatSource final : public TriangleSource {
public:
    explicit ConcatSource(std::vector<TriangleSourcePtr> parts) : parts_(std::move(parts)) {}
    size_t read(std::span<Triangle> out) override;
    void rewind() override;
    /// Skips within the current part, then on into the next ones.
    uint64_t skip(uint64_t count) override;
    std::string name() const override { return "scene"; }
    std::optional<uint64_t> sizeHint() const override;
    std::optional<uint64_t> knownSize() const override;
    /// Parts are read one after another, but all stay open: their resident bytes add up.
    uint64_t residentBytes() const override;
    std::string residentDetail() const override;
    uint32_t part() const override { return uint32_t(current_); }

private:
    std::vector<TriangleSourcePtr> parts_;
    size_t current_ = 0;
};

/// @brief Refuses NaN and infinite vertices as they stream by, naming @p where (a scene's entry)
/// and the triangle's index in it: a generator's numbers or a transform can overflow float, and
/// every writer (`generate` to .obj or .glb) and the bake must stop there, not write "inf".
class FiniteSource final : public DecoratedSource {
public:
    FiniteSource(TriangleSourcePtr inner, std::string where) : DecoratedSource(std::move(inner)), where_(std::move(where)) {}
    /// @throw InputError at the first triangle with a non-finite coordinate
    size_t read(std::span<Triangle> out) override;
    void rewind() override { inner_->rewind(), position_ = 0; }
    uint64_t skip(uint64_t count) override {
        const uint64_t n = inner_->skip(count);
        position_ += n;
        return n;
    }
    uint32_t part() const override { return inner_->part(); }

private:
    std::string where_;
    uint64_t position_ = 0;
};

/// @brief Sets and clears bits of Triangle::flags on everything another source delivers (a scene
/// entry's "closed": true or false). Marking a source closed also starts a solid at its first
/// triangle (kTriangleSolidStart), so the entry is at least one solid of its own.
class FlagSource final : public DecoratedSource {
public:
    FlagSource(TriangleSourcePtr inner, uint32_t set, uint32_t clear)
        : DecoratedSource(std::move(inner)), set_(set), keep_(~clear) {}
    size_t read(std::span<Triangle> out) override {
        const size_t n = inner_->read(out);
        for (size_t i = 0; i < n; ++i) out[i].flags = (out[i].flags & keep_) | set_;
        if (n && first_ && (set_ & kTriangleClosed)) out[0].flags |= kTriangleSolidStart;
        if (n) first_ = false;
        return n;
    }
    void rewind() override { inner_->rewind(), first_ = true; }
    /// A skipped first triangle would have carried the solid start: the next read is no longer first.
    uint64_t skip(uint64_t count) override {
        const uint64_t n = inner_->skip(count);
        if (n) first_ = false;
        return n;
    }

private:
    uint32_t set_, keep_;
    bool first_ = true;
};

/// Reads a whole source into memory. For tests and small scenes only.
std::vector<Triangle> readAll(TriangleSource& source);

/// Chunk size used by the pipeline when pulling from a source.
inline constexpr size_t kTriangleChunk = 4096;

}  // namespace penumbra
